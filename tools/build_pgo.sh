#!/usr/bin/env bash
# A profile-guided build of `velour`: the same sources, the same images, laid out by how the
# renderer actually runs (docs/BENCHMARKS.md, "A profile-guided build").
#
#   tools/build_pgo.sh           # writes target/pgo/release/velour
#   tools/build_pgo.sh --check   # and checks that it renders every shipped scene with the same
#                                # pixels as the plain release build (tools/checksums.sh)
#
# Three steps: an instrumented build (target/pgo-instrumented), renders of every shipped scene
# and peer scene with it (small images, so the counts weigh the per-sample code as a render
# does), and a build that reads the merged counts (`-C profile-use`). It needs `llvm-profdata`
# of the compiler's own LLVM version, from rustup's `llvm-tools` component (installed here when
# missing). RUSTFLAGS, if set, replaces the repository's CPU level (.cargo/config.toml), as for
# any cargo build; unset, the build is for x86-64-v3 as the plain one is.
set -euo pipefail
cd "$(dirname "$0")/.."

check=0
case "${1:-}" in
  --check) check=1 ;;
  "") ;;
  *) echo "build_pgo.sh: unknown argument '$1' (expected nothing or --check)" >&2; exit 2 ;;
esac

host=$(rustc -vV | sed -n 's/^host: //p')
profdata="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata"
if [ ! -x "$profdata" ]; then
  if command -v rustup >/dev/null; then
    rustup component add llvm-tools >&2
  fi
fi
if [ ! -x "$profdata" ]; then
  echo "build_pgo.sh: no llvm-profdata at $profdata (install rustup's llvm-tools component: rustup component add llvm-tools)" >&2
  exit 1
fi

base_flags=${RUSTFLAGS:-"-C target-cpu=x86-64-v3"}
counts=$(mktemp -d)
trap 'rm -rf "$counts"' EXIT

echo "build_pgo.sh: 1/3 the instrumented build" >&2
RUSTFLAGS="$base_flags -C profile-generate=$counts/raw" \
  cargo build --release --quiet --target-dir target/pgo-instrumented
instrumented=target/pgo-instrumented/release/velour

echo "build_pgo.sh: 2/3 renders for the counts" >&2
for scene in scenes/*.toml tools/peers/scenes/*.toml; do
  name=$(basename "$scene" .toml)
  if ! "$instrumented" render "$scene" --width 96 --height 72 --spp 16 --seed 7 --threads 2 -q \
    --checkpoint 100000 -o "$counts/$name.exr" >"$counts/$name.log" 2>&1; then
    echo "build_pgo.sh: $scene did not render with the instrumented build (left out of the counts): $(tail -1 "$counts/$name.log")" >&2
  fi
done
"$profdata" merge -o "$counts/velour.profdata" "$counts/raw"

echo "build_pgo.sh: 3/3 the build from the counts" >&2
RUSTFLAGS="$base_flags -C profile-use=$counts/velour.profdata" \
  cargo build --release --quiet --target-dir target/pgo
echo "build_pgo.sh: wrote target/pgo/release/velour" >&2

if [ "$check" = 1 ]; then
  cargo build --release --quiet
  plain=$counts/plain.md
  guided=$counts/guided.md
  tools/checksums.sh target/release/velour >"$plain"
  tools/checksums.sh target/pgo/release/velour >"$guided"
  if ! diff "$plain" "$guided"; then
    echo "build_pgo.sh: the profile-guided build renders different pixels from the plain build (rows above)" >&2
    exit 1
  fi
  if grep -q "render failed" "$plain"; then
    echo "build_pgo.sh: a scene failed to render: $(grep "render failed" "$plain" | head -1)" >&2
    exit 1
  fi
  echo "build_pgo.sh: every scene's pixels equal the plain build's ($(grep -c '^| [a-z]' "$plain") scenes)" >&2
fi
