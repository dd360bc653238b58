#!/usr/bin/env bash
# Light tracing and BDPT against the path tracers, time against error (`ember bench`) on two
# scenes where connections from the light matter:
#   bonus  TinyRender's A5 bonus Cornell box (../shared/tinyrender/data/a5/bonus_bdpt): its
#          light faces the ceiling inside a fixture, so camera paths rarely reach it;
#   glass  ember's mirror and glass box (data/mirror-glass): caustics under the glass sphere.
# Each reference is an independent long BDPT render (seed 1; the ladders use other seeds).
# Writes bench/bdpt/<scene>/bench.{csv,svg} and prints the CPU it ran on.
# Usage: bench/bdpt/run.sh [WIDTH HEIGHT REF_SPP BUDGET_S]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
W="${1:-160}" H="${2:-120}" REF_SPP="${3:-1024}" BUDGET="${4:-8}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
cargo build --release -q -p ember-cli --manifest-path "$ROOT/Cargo.toml"
EMBER="$CARGO_TARGET_DIR/release/ember"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) threads"
echo "SIMD: $(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -xE 'sse4_2|avx|avx2|fma|avx512f|avx512dq|avx512bw|avx512vl|neon' | tr '\n' ' ')"
run() {
    local name=$1 scene=$2
    local out="$HERE/$name"
    mkdir -p "$out"
    echo "== $name: reference, BDPT $REF_SPP spp at ${W}x$H"
    "$EMBER" render "$scene" --integrator bdpt --sampler independent --spp "$REF_SPP" --seed 1 --width "$W" \
        --height "$H" -o "$out/ref.exr" | tail -n 2
    "$EMBER" bench "$scene" --reference "$out/ref.exr" --integrators mis,explicit,lighttracer,bdpt \
        --budget "$BUDGET" --seed 77 -o "$out" -q
    rm -f "$out/ref.exr" "$out/ref.png"
}
run bonus "$ROOT/../shared/tinyrender/data/a5/bonus_bdpt/tinyrender/cbox_bdpt.toml"
run glass "$ROOT/data/mirror-glass/mirror_glass.toml"
