#!/usr/bin/env bash
# nee = "exit" against nee = "exit_guided" (docs/choosing-estimators.md): for each scene, two
# renders at seeds 11 and 12, the rel. MSE between them (`velour diff --json`), the CPU time
# (user + sys) per render, and the efficiency 1/(rel. MSE x CPU s).
#
#   tools/bench_exit_guided.sh [VELOUR_BINARY]    # default: target/release/velour
#   SCENES="tex" tools/bench_exit_guided.sh       # only some rows (default: repro skin ico tex)
#
# Scenes: the reproducer (a dense r = 1 sphere behind a roughness-0.3 dielectric under a 1° sun),
# scenes/skin_sphere.toml, tools/peers/bench/skin_icosphere.toml (its mesh generated here), and
# "tex": the reproducer behind a textured boundary (roughness 0.45 with smoother veins at 0.24,
# and a tinted skin with darker veins, both from tools/make_texture.py's veins image).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
cat >"$out/repro_exit.toml" <<'TOML'
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 24
[film]
width = 64
height = 64
spp = 16
max_depth = 1000
[[light]]
type = "distant"
direction = [-0.6, 0.8, 0.5]
irradiance = [4.0, 4.0, 4.0]
angular_radius = 1.0
[[object]]
name = "skin"
shape = "sphere"
radius = 1.0
surface = { type = "dielectric", ior = 1.4, roughness = 0.3 }
interior = { type = "homogeneous", albedo = 0.95, albedo_mode = "single", density = 20.0, nee = "exit" }
TOML
sed "s#meshes/#$PWD/scenes/meshes/#" scenes/skin_sphere.toml >"$out/skin_exit.toml"
python3 tools/peers/make_icosphere.py --subdivisions 5 "$out/ico.ply" >/dev/null
# skin_icosphere.toml leaves nee to the default (exit_guided there): spell out "exit".
sed -e "s#../generated/icosphere_20k.ply#$out/ico.ply#" \
  -e 's/attenuation = \[2.25, 1.5, 1.0\] }/attenuation = [2.25, 1.5, 1.0], nee = "exit" }/' \
  tools/peers/bench/skin_icosphere.toml >"$out/ico_exit.toml"
grep -q 'nee = "exit"' "$out/ico_exit.toml"
python3 tools/make_texture.py veins "$out/veins.png" >/dev/null
sed -e "s#roughness = 0.3 }#roughness = { texture = \"$out/veins.png\", channel = \"r\", scale = 0.5 }, tint = { texture = \"$out/veins.png\" } }#" \
  "$out/repro_exit.toml" >"$out/tex_exit.toml"
for s in repro skin ico tex; do
  sed 's/nee = "exit"/nee = "exit_guided"/' "$out/${s}_exit.toml" >"$out/${s}_guided.toml"
done
cat /proc/loadavg
for s in "repro 16" "skin 8" "ico 4" "tex 16"; do
  set -- $s
  case " ${SCENES:-repro skin ico tex} " in *" $1 "*) ;; *) continue ;; esac
  for nee in exit guided; do
    cpu=()
    for seed in 11 12; do
      t=$( { /usr/bin/time -f "%U %S" "$bin" render "$out/${1}_$nee.toml" -q --spp "$2" --seed $seed \
        --checkpoint 100000 -o "$out/$seed.exr" >/dev/null; } 2>&1 | tail -1)
      cpu+=("$(echo "$t" | awk '{print $1 + $2}')")
    done
    # awk reads the whole report (grep -m1 could close the pipe early: SIGPIPE under pipefail).
    rel=$("$bin" diff --json "$out/11.exr" "$out/12.exr" |
      awk '/"rel_mse"/ && !f { f = 1; sub(/.*: */, ""); sub(/,.*/, ""); print }')
    awk -v s="$1" -v n="$nee" -v a="${cpu[0]}" -v b="${cpu[1]}" -v r="$rel" \
      'BEGIN { c = (a + b) / 2; printf "%-6s %-7s cpu %.2f s  rel_mse %.4g  efficiency %.4g\n", s, n, c, r, 1 / (r * c) }'
  done
done
cat /proc/loadavg
