#!/usr/bin/env bash
# ember against Mitsuba 3 on the Cornell box (data/cornell-box; another scene with SCENE=...,
# e.g. SCENE=data/mirror-glass/mirror_glass.toml WIDTH=320 HEIGHT=240): relative MSE against time for
# ember's `mis` integrator and Mitsuba's `path` integrator (scalar_rgb and llvm_ad_rgb), same
# scene, film, threads and reference, in one run on one machine. See mitsuba_bench.py.
#
#   bench/mitsuba/run.sh                       # 256x256, 2 threads, 4096-spp references
#   SCENE=tinyrender-cbox bench/mitsuba/run.sh # TinyRender's cbox.obj, sphere made diffuse
#   EMBER_NATIVE=1 bench/mitsuba/run.sh        # also ember built with -C target-cpu=native
#   MITSUBA_LLVM_TARGET=avx2 EMBER_NATIVE=1 EMBER_NATIVE_CPU=x86-64-v3 OUT=bench/mitsuba/avx2 \
#       bench/mitsuba/run.sh                   # both limited to AVX2 (8 lanes), as on an AVX2 machine
#   REF_SPP=128 MITSUBA_REF_SPP=128 SPLITS=8 BUDGET=0.5 MAX_SPP=16 OUT=/tmp/smoke \
#       bench/mitsuba/run.sh                   # a quick smoke run (a few minutes)
#
# Writes bench/mitsuba/{results.csv, bench.csv, bench.svg, table.md}; intermediate files
# (converted scene, EXRs) go to bench/mitsuba/build/. Needs the network for PyPI (mitsuba,
# numpy: ~300 MB installed) and Debian (libllvm19) on the first run. Run it on a quiet machine:
# the figures are only comparable within one run.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"

SCENE="${SCENE:-data/cornell-box/cornell_box.toml}"   # relative to the repository root, or absolute
SIZE="${SIZE:-256}"
WIDTH="${WIDTH:-$SIZE}"
HEIGHT="${HEIGHT:-$SIZE}"
THREADS="${THREADS:-2}"
REF_SPP="${REF_SPP:-4096}"
MITSUBA_REF_SPP="${MITSUBA_REF_SPP:-4096}"
SPLITS="${SPLITS:-16}"
BUDGET="${BUDGET:-10}"
MAX_SPP="${MAX_SPP:-65536}"
EMBER_SAMPLERS="${EMBER_SAMPLERS:-independent,zsobol}"   # one ember ladder and table each
MITSUBA_SAMPLERS="${MITSUBA_SAMPLERS:-independent}"      # e.g. independent,stratified,multijitter,orthogonal,ldsampler
# Runs of every ladder, Mitsuba's and ember's first in turn, each rung keeping its fastest time
# (this instance's speed drifts by 5-10% over minutes; see mitsuba_bench.py).
ROUNDS="${ROUNDS:-2}"
# What the llvm variants compile for: native (Dr.Jit's choice: 16 lanes with AVX-512) or avx2
# (Haswell, 8 lanes: an AVX2 machine's code on this CPU; pair it with EMBER_NATIVE=1
# EMBER_NATIVE_CPU=x86-64-v3 and an OUT of its own).
MITSUBA_LLVM_TARGET="${MITSUBA_LLVM_TARGET:-native}"
# At AVX2 width ember keeps to eight lanes too (its AVX-512 dispatch off: kernel/src/simd.rs).
if [ "$MITSUBA_LLVM_TARGET" = avx2 ]; then export EMBER_SIMD="${EMBER_SIMD:-avx2}"; fi
# Where results.csv, bench.csv, bench.svg and table.md go: this folder for the Cornell box,
# bench/mitsuba/<scene stem>/ for another scene.
if [ "$SCENE" = data/cornell-box/cornell_box.toml ]; then OUT="${OUT:-$HERE}"
else OUT="${OUT:-$HERE/$(basename "$SCENE" .toml)}"; fi

source "$HERE/env.sh"   # venv with Mitsuba and numpy, LLVM 19, ember (release)

# SCENE=tinyrender-cbox: TinyRender's own Cornell box (a5/cbox: cbox.obj, 32k triangles,
# cbox_path_explicit_rr.toml's camera and path settings) with its sphere made diffuse
# (`rightSphere` is TinyRender's Phong/diffuse mixture, illum 8, which Mitsuba lacks; its Kd is
# kept), copied to $OUT/scene so that both renderers read the same files. Film 320x240 (the
# scene's 4:3) unless WIDTH/HEIGHT say otherwise.
if [ "$SCENE" = tinyrender-cbox ]; then
    TINYRENDER="${EMBER_TINYRENDER:-$ROOT/../shared/tinyrender}"
    src="$TINYRENDER/data/a5/cbox"
    mkdir -p "$OUT/scene/mesh"
    cp "$src/mesh/cbox.obj" "$OUT/scene/mesh/"
    awk '$1 == "newmtl" { m = $2 } m == "rightSphere" && $1 == "illum" { print "illum 7"; next } { print }' \
        "$src/mesh/cbox.mtl" >"$OUT/scene/mesh/cbox.mtl"
    sed 's|^objfile = .*|objfile = "mesh/cbox.obj"|' "$src/tinyrender/cbox_path_explicit_rr.toml" \
        >"$OUT/scene/cbox_diffuse.toml"
    grep -q 'objfile = "mesh/cbox.obj"' "$OUT/scene/cbox_diffuse.toml"
    SCENE="$OUT/scene/cbox_diffuse.toml"
    [ "$SIZE" = 256 ] && [ "$WIDTH" = 256 ] && WIDTH=320 && HEIGHT=240
fi

case "$SCENE" in /*) SCENE_PATH="$SCENE" ;; *) SCENE_PATH="$ROOT/$SCENE" ;; esac
exec "$VENV/bin/python" "$HERE/mitsuba_bench.py" --ember "$EMBER" \
    --scene "$SCENE_PATH" --width "$WIDTH" --height "$HEIGHT" --threads "$THREADS" \
    --ref-spp "$REF_SPP" --mitsuba-ref-spp "$MITSUBA_REF_SPP" --splits "$SPLITS" \
    --budget "$BUDGET" --max-spp "$MAX_SPP" --ember-samplers "$EMBER_SAMPLERS" \
    --mitsuba-samplers "$MITSUBA_SAMPLERS" --out "$OUT" --llvm-target "$MITSUBA_LLVM_TARGET" \
    --rounds "$ROUNDS" \
    ${EMBER_NATIVE_BIN:+--ember-native "$EMBER_NATIVE_BIN" --ember-native-name "target-cpu=$EMBER_NATIVE_CPU build"}
