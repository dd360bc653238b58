#!/usr/bin/env bash
# The GI bake's run time on 2 cores: issue 14's target is the cubebox-sized bake (35k
# triangles, 19k unique vertices, 300 paths each) in under 10 s. Bakes the scene that
# make_cubebox.py writes (34,880 triangles, 18,496 vertex keys) and TinyRender's
# cbox_gi_high_realtime.toml, with the shipped build and one for this CPU
# (-C target-cpu=native), alternating, RUNS times each; prints the medians, the CPU and its
# SIMD flags, and whether the two builds' PLYs are identical. Writes bench/bake/table.md.
# Extra arguments go to `ember bake` (e.g. --threads 1).
# Usage: bench/bake/run.sh [RUNS] [-- BAKE ARGS]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
RUNS="${1:-3}"
shift || true
[ "${1:-}" = "--" ] && shift
TINYRENDER="${EMBER_TINYRENDER:-$ROOT/../shared/tinyrender}"
base="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT

declare -A bin=([shipped]="$base/release/ember" [native]="$base-native/release/ember")
(cd "$ROOT" && CARGO_TARGET_DIR="$base" cargo build --release -q -p ember-cli)
(cd "$ROOT" && RUSTFLAGS="-C target-cpu=native" CARGO_TARGET_DIR="$base-native" \
    cargo build --release -q -p ember-cli)

python3 "$HERE/make_cubebox.py" "$out/cubebox" >/dev/null
cp -r "$TINYRENDER/data/a5/cbox" "$out/cbox"
declare -A scene=(
    [cubebox]="$out/cubebox/cubebox_gi.toml"
    [cbox_gi_high]="$out/cbox/tinyrender/cbox_gi_high_realtime.toml"
)

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }

exec > >(tee "$HERE/table.md")
echo "# GI bake times ($(date -u '+%Y-%m-%d %H:%M') UTC, medians of $RUNS alternating runs, $(nproc) threads${*:+, ember bake $*})"
echo
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) threads"
echo
echo "SIMD: $(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -xE 'sse4_2|avx|avx2|fma|avx512f|avx512dq|avx512bw|avx512vl|neon' | tr '\n' ' ')"
echo
echo "| scene | vertex keys x paths | shipped build (s) | native build (s) | same PLY |"
echo "|---|---|---|---|---|"
for s in cubebox cbox_gi_high; do
    declare -A times=()
    for ((r = 0; r < RUNS; r++)); do
        for v in shipped native; do
            line="$("${bin[$v]}" bake "${scene[$s]}" -o "$out/$s.$v.ply" "$@" 2>&1 | grep 'baked')"
            secs="$(sed -E 's/.* in ([0-9.]+) s,.*/\1/' <<<"$line")"
            times[$v]+="$secs "
            keys="$(sed -E 's/.*baked ([0-9]+) vertex keys.* x ([0-9]+) samples.*/\1 x \2/' <<<"$line")"
        done
    done
    same="no"
    cmp -s "$out/$s.shipped.ply" "$out/$s.native.ply" && same="yes"
    echo "| $s | $keys | $(tr ' ' '\n' <<<"${times[shipped]}" | grep . | median) | $(tr ' ' '\n' <<<"${times[native]}" | grep . | median) | $same |"
    unset times
done
