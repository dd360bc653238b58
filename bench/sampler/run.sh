#!/usr/bin/env bash
# The independent and the ZSobol sampler, time against error (`ember bench`) on ember's Cornell
# box at 96x96 for every integrator, against an independent MIS reference of 8192 spp (seed 1;
# the ladders use other seeds). Writes bench/sampler/<sampler>/bench.{csv,svg} and prints the
# CPU it ran on.
# Usage: bench/sampler/run.sh [BUDGET_S]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
BUDGET="${1:-2}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
cargo build --release -q -p ember-cli --manifest-path "$ROOT/Cargo.toml"
EMBER="$CARGO_TARGET_DIR/release/ember"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) threads"
echo "SIMD: $(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -xE 'sse4_2|avx|avx2|fma|avx512f|avx512dq|avx512bw|avx512vl|neon' | tr '\n' ' ')"
scene="$ROOT/data/cornell-box/cornell_box.toml"
ref="$(mktemp -d)/ref.exr"
"$EMBER" render "$scene" --integrator mis --sampler independent --spp 8192 --seed 1 --width 96 --height 96 -o "$ref" | tail -n 2
for sampler in independent zsobol; do
    "$EMBER" bench "$scene" --reference "$ref" --integrators mis,explicit,implicit,lighttracer,bdpt \
        --budget "$BUDGET" --max-spp 512 --seed 78 --sampler "$sampler" -o "$HERE/$sampler" -q
done
rm -rf "$(dirname "$ref")"
