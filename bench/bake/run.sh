#!/usr/bin/env bash
# The GI bake's run time against its error on 2 cores: issue 14's target is the cubebox-sized
# bake (35k triangles, 19k unique vertices, 300 paths each) in under 10 s. Bakes the scene that
# make_cubebox.py writes (34,880 triangles, 18,496 vertex keys) and TinyRender's
# cbox_gi_high_realtime.toml (both maxDepth 12, rrDepth 5), each as written (MIS's adaptive
# roulette from bounce 5) and with roulette off (rrDepth = maxDepth: every path 12 bounces),
# with the shipped build and one for this CPU (-C target-cpu=native), alternating, RUNS times
# each. Prints the medians, the CPU and its SIMD flags, whether the two builds' PLYs are
# identical, and each bake's error against a reference bake of REF_SAMPLES paths per vertex
# (another seed, roulette off, shipped build; REF_SAMPLES=0 skips it): MSE and relMSE over the
# vertices, and time x relMSE, which for one estimator does not depend on the path count, so
# its ratio between two rows is their ratio of time to equal error. Writes bench/bake/table.md.
# Extra arguments go to `ember bake` (e.g. --threads 1).
# Usage: [REF_SAMPLES=4800] bench/bake/run.sh [RUNS] [-- BAKE ARGS]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
RUNS="${1:-3}"
shift || true
[ "${1:-}" = "--" ] && shift
REF_SAMPLES="${REF_SAMPLES:-4800}"
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
# Roulette off: the same scene with rrDepth = maxDepth (the last ray of a bounded path is
# always traced, so no bounce is left for roulette).
no_roulette() { sed -E 's/^rrDepth = .*/rrDepth = 12/' "$1" >"$2"; grep -q '^maxDepth = 12$' "$2"; }
no_roulette "$out/cubebox/cubebox_gi.toml" "$out/cubebox/cubebox_gi_off.toml"
no_roulette "$out/cbox/tinyrender/cbox_gi_high_realtime.toml" \
    "$out/cbox/tinyrender/cbox_gi_high_off.toml"
declare -A scene=(
    [cubebox]="$out/cubebox/cubebox_gi.toml"
    [cubebox_off]="$out/cubebox/cubebox_gi_off.toml"
    [cbox_gi_high]="$out/cbox/tinyrender/cbox_gi_high_realtime.toml"
    [cbox_gi_high_off]="$out/cbox/tinyrender/cbox_gi_high_off.toml"
)

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }

# The references (before the timed runs, which they would otherwise disturb).
if [ "$REF_SAMPLES" -gt 0 ]; then
    for s in cubebox cbox_gi_high; do
        "${bin[shipped]}" bake "${scene[${s}_off]}" -o "$out/$s.ref.ply" -q --seed 1 \
            --samples-per-vertex "$REF_SAMPLES" "$@" >/dev/null
    done
fi

exec > >(tee "$HERE/table.md")
echo "# GI bake times and errors ($(date -u '+%Y-%m-%d %H:%M') UTC, medians of $RUNS alternating runs, $(nproc) threads${*:+, ember bake $*})"
echo
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) threads"
echo
echo "SIMD: $(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -xE 'sse4_2|avx|avx2|fma|avx512f|avx512dq|avx512bw|avx512vl|neon' | tr '\n' ' ')"
echo
if [ "$REF_SAMPLES" -gt 0 ]; then
    echo "Error against a $REF_SAMPLES-path bake with roulette off (seed 1; its own noise adds about 300/$REF_SAMPLES of a 300-path bake's to every row)."
    echo
fi
echo "| scene | roulette | vertex keys x paths | shipped build (s) | native build (s) | same PLY | MSE | relMSE | shipped s x relMSE |"
echo "|---|---|---|---|---|---|---|---|---|"
for s in cubebox cubebox_off cbox_gi_high cbox_gi_high_off; do
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
    shipped="$(tr ' ' '\n' <<<"${times[shipped]}" | grep . | median)"
    native="$(tr ' ' '\n' <<<"${times[native]}" | grep . | median)"
    roulette="from bounce 5"
    [[ "$s" == *_off ]] && roulette="off"
    err="- | - | -"
    if [ "$REF_SAMPLES" -gt 0 ]; then
        read -r _ mse rel < <(python3 "$HERE/error.py" "$out/${s%_off}.ref.ply" "$out/$s.shipped.ply")
        err="$mse | $rel | $(python3 -c "print(f'{$shipped * $rel:.3e}')")"
    fi
    echo "| ${s%_off} | $roulette | $keys | $shipped | $native | $same | $err |"
    unset times
done
