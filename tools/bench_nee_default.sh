#!/usr/bin/env bash
# The default nee (docs/choosing-estimators.md, "Next event estimation"): nee = "exit" against
# nee = "exit_guided" on every case the default rule decides, with tools/bench_exit_guided.sh's
# method: two renders at seeds 11 and 12, the rel. MSE between them (`velour diff --json`), the
# CPU time (user + sys) per render, and the efficiency 1/(rel. MSE x CPU s).
#
#   tools/bench_nee_default.sh [VELOUR_BINARY]    # default: target/release/velour
#   ROWS="ico ico_sky" tools/bench_nee_default.sh # only some rows
#
# Rows (the reproducer: a dense r = 1 sphere, density 20, albedo 0.95, behind a roughness-0.3
# dielectric, 64x64):
#   ico        tools/peers/bench/skin_icosphere.toml (constant sky + delta sun), 4 spp
#   ico_sky    the same without the sun (environment only), 4 spp
#   peer_skin  tools/peers/scenes/skin_rough_dielectric.toml (sky + delta sun, roughness 0.35), 16 spp
#   skin       scenes/skin_sphere.toml (sky + 2 deg sun, roughness 0.6), 8 spp
#   sun        the reproducer under a 1 deg sun, 16 spp
#   sphere     the reproducer under a sphere light (r 0.5), 16 spp
#   sky        the reproducer under a constant environment only, 16 spp
#   thin       the reproducer at density 2 under the 1 deg sun, 16 spp
#   tex        the reproducer behind a textured roughness (0.45, veins 0.24), 16 spp
#   blend      a blend of two rough looks (0.3 and 0.7) under a veins mask, 16 spp
#   blend_sm   a blend of a smooth and a rough (0.3) look under the veins mask, 16 spp
#   coat       the reproducer's boundary with a coat (ior 1.5, roughness 0.1), 16 spp
#   coat_sph   the same under the sphere light, 16 spp
#   blend_coat a blend of the rough look and the coated look under the veins mask, 16 spp
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
python3 tools/peers/make_icosphere.py --subdivisions 5 "$out/ico.ply" >/dev/null
python3 tools/make_texture.py veins "$out/veins.png" >/dev/null
SUN='[[light]]
type = "distant"
direction = [-0.6, 0.8, 0.5]
irradiance = [4.0, 4.0, 4.0]
angular_radius = 1.0'
SPHERE='[[light]]
type = "sphere"
center = [-1.5, 2.0, 1.5]
radius = 0.5
radiance = 10.0'
SKY='[[light]]
type = "environment"
radiance = [0.35, 0.4, 0.5]'
repro() { # lights, surface, density
  cat <<TOML
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 24
[film]
width = 64
height = 64
spp = 16
max_depth = 1000
$1
[[object]]
name = "skin"
shape = "sphere"
radius = 1.0
surface = $2
interior = { type = "homogeneous", albedo = 0.95, albedo_mode = "single", density = ${3:-20.0}, nee = "NEE" }
TOML
}
R03='{ type = "dielectric", ior = 1.4, roughness = 0.3 }'
V="$out/veins.png"
sed -e "s#../generated/icosphere_20k.ply#$out/ico.ply#" -e 's/nee = "[a-z_]*"/nee = "NEE"/' \
  -e 's/attenuation = \[2.25, 1.5, 1.0\] }/attenuation = [2.25, 1.5, 1.0], nee = "NEE" }/' \
  tools/peers/bench/skin_icosphere.toml >"$out/ico.toml"
# The same without its distant light (the [[light]] table whose type is "distant").
python3 - "$out/ico.toml" >"$out/ico_sky.toml" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
print(re.sub(r'\[\[light\]\]\ntype = "distant"\n(?:[a-z_]+ = .*\n)*', "", text), end="")
PY
sed -e 's/nee = "[a-z_]*"/nee = "NEE"/' tools/peers/scenes/skin_rough_dielectric.toml |
  grep -v '^output' >"$out/peer_skin.toml"
sed -e "s#meshes/#$PWD/scenes/meshes/#" -e 's/nee = "[a-z_]*"/nee = "NEE"/' scenes/skin_sphere.toml |
  grep -v '^output' >"$out/skin.toml"
repro "$SUN" "$R03" >"$out/sun.toml"
repro "$SPHERE" "$R03" >"$out/sphere.toml"
repro "$SKY" "$R03" >"$out/sky.toml"
repro "$SUN" "$R03" 2.0 >"$out/thin.toml"
repro "$SUN" "{ type = \"dielectric\", ior = 1.4, roughness = { texture = \"$V\", channel = \"r\", scale = 0.5 }, tint = { texture = \"$V\" } }" >"$out/tex.toml"
repro "$SUN" "{ type = \"blend\", mask = { texture = \"$V\", channel = \"r\" }, a = { type = \"dielectric\", ior = 1.4, roughness = 0.3 }, b = { type = \"dielectric\", ior = 1.4, roughness = 0.7, tint = [0.9, 0.6, 0.5] } }" >"$out/blend.toml"
repro "$SUN" "{ type = \"blend\", mask = { texture = \"$V\", channel = \"r\" }, a = { type = \"dielectric\", ior = 1.4 }, b = { type = \"dielectric\", ior = 1.4, roughness = 0.3 } }" >"$out/blend_sm.toml"
COATED='{ type = "dielectric", ior = 1.4, roughness = 0.3, coat = { ior = 1.5, roughness = 0.1 } }'
repro "$SUN" "$COATED" >"$out/coat.toml"
repro "$SPHERE" "$COATED" >"$out/coat_sph.toml"
repro "$SUN" "{ type = \"blend\", mask = { texture = \"$V\", channel = \"r\" }, a = $R03, b = $COATED }" >"$out/blend_coat.toml"
cat /proc/loadavg
for row in "ico 4" "ico_sky 4" "peer_skin 16" "skin 8" "sun 16" "sphere 16" "sky 16" "thin 16" "tex 16" "blend 16" "blend_sm 16" "coat 16" "coat_sph 16" "blend_coat 16"; do
  set -- $row
  case " ${ROWS:-ico ico_sky peer_skin skin sun sphere sky thin tex blend blend_sm coat coat_sph blend_coat} " in *" $1 "*) ;; *) continue ;; esac
  for nee in exit exit_guided; do
    sed "s/nee = \"NEE\"/nee = \"$nee\"/" "$out/$1.toml" >"$out/run.toml"
    grep -q "nee = \"$nee\"" "$out/run.toml"
    cpu=()
    for seed in 11 12; do
      t=$( { /usr/bin/time -f "%U %S" "$bin" render "$out/run.toml" -q --spp "$2" --seed $seed \
        --checkpoint 100000 -o "$out/$seed.exr" >/dev/null; } 2>&1 | tail -1)
      cpu+=("$(echo "$t" | awk '{print $1 + $2}')")
    done
    rel=$("$bin" diff --json "$out/11.exr" "$out/12.exr" |
      awk '/"rel_mse"/ && !f { f = 1; sub(/.*: */, ""); sub(/,.*/, ""); print }')
    awk -v s="$1" -v n="$nee" -v a="${cpu[0]}" -v b="${cpu[1]}" -v r="$rel" \
      'BEGIN { c = (a + b) / 2; printf "%-9s %-11s cpu %.2f s  rel_mse %.4g  efficiency %.4g\n", s, n, c, r, 1 / (r * c) }'
  done
done
cat /proc/loadavg
