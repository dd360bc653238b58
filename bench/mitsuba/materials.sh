#!/usr/bin/env bash
# Mitsuba 3 references of the mirror/glass Cornell boxes (data/mirror-glass) for the CI test
# tests/tests/mitsuba_materials.rs: K independent renders per scene, their mean and the
# per-pixel variance of the mean, written to bench/mitsuba/refs/. See materials.py and
# refs/README.md. CI never runs this: the test reads the committed EXRs.
#
#   bench/mitsuba/materials.sh                 # 160x120, 16 renders x 256 spp, scalar_rgb, 2 threads
#   SPP=16 SPLITS=4 OUT=/tmp/refs bench/mitsuba/materials.sh   # a quick smoke run
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"

WIDTH="${WIDTH:-160}"
HEIGHT="${HEIGHT:-120}"
SPLITS="${SPLITS:-16}"
SPP="${SPP:-256}"
VARIANT="${VARIANT:-scalar_rgb}"
THREADS="${THREADS:-2}"
OUT="${OUT:-$HERE/refs}"

# scalar_rgb needs no LLVM; the llvm_ad_* variants do.
case "$VARIANT" in llvm_*) NEED_LLVM=1 ;; *) NEED_LLVM=0 ;; esac
NEED_EMBER=0            # the references are Mitsuba's alone
source "$HERE/env.sh"   # venv with Mitsuba and numpy (and LLVM 19 for llvm variants)

exec "$VENV/bin/python" "$HERE/materials.py" --width "$WIDTH" --height "$HEIGHT" \
    --splits "$SPLITS" --spp "$SPP" --variant "$VARIANT" --threads "$THREADS" --out "$OUT" "$@"
