#!/usr/bin/env bash
# ember against Mitsuba 3 on the Cornell box (data/cornell-box): relative MSE against time for
# ember's `mis` integrator and Mitsuba's `path` integrator (scalar_rgb and llvm_ad_rgb), same
# scene, film, threads and reference, in one run on one machine. See mitsuba_bench.py.
#
#   bench/mitsuba/run.sh                       # 256x256, 2 threads, 4096-spp references
#   REF_SPP=128 MITSUBA_REF_SPP=128 SPLITS=8 BUDGET=0.5 MAX_SPP=16 OUT=/tmp/smoke \
#       bench/mitsuba/run.sh                   # a quick smoke run (a few minutes)
#
# Writes bench/mitsuba/{results.csv, bench.csv, bench.svg, table.md}; intermediate files
# (converted scene, EXRs) go to bench/mitsuba/build/. Needs the network for PyPI (mitsuba,
# numpy: ~300 MB installed) and Debian (libllvm19) on the first run. Run it on a quiet machine:
# the figures are only comparable within one run.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
VENV="$ROOT/bench/venv"

SIZE="${SIZE:-256}"
THREADS="${THREADS:-2}"
REF_SPP="${REF_SPP:-4096}"
MITSUBA_REF_SPP="${MITSUBA_REF_SPP:-4096}"
SPLITS="${SPLITS:-16}"
BUDGET="${BUDGET:-10}"
MAX_SPP="${MAX_SPP:-65536}"
OUT="${OUT:-$HERE}"          # where results.csv, bench.csv, bench.svg and table.md go

# Python environment with Mitsuba 3 and numpy.
if [ ! -x "$VENV/bin/python" ]; then
    echo "== creating $VENV"
    python3 -m venv "$VENV"
fi
if ! "$VENV/bin/python" -c 'import mitsuba, numpy' 2>/dev/null; then
    echo "== pip install mitsuba numpy"
    "$VENV/bin/pip" install --quiet --upgrade pip
    "$VENV/bin/pip" install --quiet mitsuba numpy
fi

# Mitsuba's llvm_ad_* variants JIT-compile through LLVM, which the wheel does not ship.
find_llvm() { find /usr/lib /usr/local/lib -name 'libLLVM*.so*' 2>/dev/null | sort -V | tail -n 1; }
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
    if [ -z "$(find /usr/lib -name 'libLLVM-19*.so*' 2>/dev/null | head -n 1)" ]; then
        echo "== apt-get install libllvm19"
        if [ "$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libllvm19 >/dev/null
    fi
    DRJIT_LIBLLVM_PATH="$(find /usr/lib -name 'libLLVM-19*.so*' 2>/dev/null | sort | head -n 1)"
    [ -n "$DRJIT_LIBLLVM_PATH" ] || DRJIT_LIBLLVM_PATH="$(find_llvm)"
    export DRJIT_LIBLLVM_PATH
fi
echo "== DRJIT_LIBLLVM_PATH=$DRJIT_LIBLLVM_PATH"

# ember, optimised.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
echo "== cargo build --release -p ember-cli"
(cd "$ROOT" && cargo build --release --quiet -p ember-cli --bin ember)
EMBER="$CARGO_TARGET_DIR/release/ember"

exec "$VENV/bin/python" "$HERE/mitsuba_bench.py" --ember "$EMBER" \
    --scene "$ROOT/data/cornell-box/cornell_box.toml" --size "$SIZE" --threads "$THREADS" \
    --ref-spp "$REF_SPP" --mitsuba-ref-spp "$MITSUBA_REF_SPP" --splits "$SPLITS" \
    --budget "$BUDGET" --max-spp "$MAX_SPP" --out "$OUT"
