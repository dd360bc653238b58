#!/usr/bin/env bash
# ember's BVH against Intel Embree on bench-embree's triangles and rays (shared/bench-embree),
# in one run on one machine: Mrays/s per scene x ray set x query x threads, build time, memory,
# and a ray-by-ray check of ember's hits against Embree's. See README.md beside this script.
#
#   bench/embree/run.sh                              # everything (~10 min on a quiet 2-core machine)
#   SCENES=cbox,sphere_1k ROUNDS=1 bench/embree/run.sh   # a smoke run (~1 min)
#   LOCKSTEP_ONLY=1 bench/embree/run.sh             # only the lockstep ratios (lockstep.md)
#   EMBREE_ISA=avx2 NATIVE_RUSTFLAGS="-C target-cpu=x86-64-v3" OUT=bench/embree/avx2 \
#       bench/embree/run.sh                      # both limited to AVX2, as on an AVX2 machine
#
# Work files go to $WORK (default /tmp/embree-data): the Python venv (embreex, numpy), a copy of
# bench-embree's scripts with the generated scenes and rays (~430 MB, deterministic) and Embree's
# results. Nothing is written to shared/. Writes bench/embree/table.md and bench/embree/results/.
# Needs PyPI on the first run. Run it on a quiet machine: the figures compare within one run only.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
SRC="${EMBER_BENCH_EMBREE:-$ROOT/../shared/bench-embree}"       # make_data.py, bench.py
TINYRENDER="${EMBER_TINYRENDER:-$ROOT/../shared/tinyrender}"     # the Cornell box OBJ
WORK="${WORK:-/tmp/embree-data}"
SCENES="${SCENES:-cbox,sphere_1k,sphere_10k,sphere_100k,sphere_1m}"
ROUNDS="${ROUNDS:-3}"           # bench.py rounds (a fresh process and BVH each)
PASSES="${PASSES:-3}"           # timed passes per configuration (after one warm-up)
OUT="${OUT:-$HERE}"             # where table.md and results/ go
# Embree's instruction set (its device config `isa=`, e.g. avx2): empty for Embree's own choice
# (AVX-512 where the CPU has it). embreex cannot pass a device config, so rtc_config.c, loaded
# with LD_PRELOAD, hands rtcNewDevice one; the ISA Embree then reports goes into table.md.
EMBREE_ISA="${EMBREE_ISA:-}"
VENV="$WORK/venv"
DATA="$WORK/bench-embree"
RES="$OUT/results"

[ -f "$SRC/make_data.py" ] && [ -f "$SRC/bench.py" ] || { echo "no bench-embree at $SRC (set EMBER_BENCH_EMBREE)" >&2; exit 1; }
mkdir -p "$WORK" "$DATA" "$RES"

if [ ! -x "$VENV/bin/python" ]; then
    echo "== creating $VENV"
    python3 -m venv "$VENV"
fi
if ! "$VENV/bin/python" -c 'import embreex, numpy' 2>/dev/null; then
    echo "== pip install embreex numpy"
    "$VENV/bin/pip" install --quiet embreex numpy
fi

# bench-embree's scripts write next to themselves and read the Cornell box from
# ../tinyrender/data/a5/cbox/mesh/cbox.obj: run a copy in $DATA with that link beside it.
for f in make_data.py bench.py README.md; do
    cmp -s "$SRC/$f" "$DATA/$f" || install -m 644 "$SRC/$f" "$DATA/$f"
done
ln -sfn "$TINYRENDER" "$WORK/tinyrender"

missing=""
for s in ${SCENES//,/ }; do
    for f in "scenes/bin/${s}_V.npy" "rays/${s}_shadow_tfar.npy"; do
        [ -f "$DATA/$f" ] || missing="$missing,$s"
    done
done
if [ -n "$missing" ]; then
    echo "== make_data.py --only ${missing#,}"
    (cd "$DATA" && "$VENV/bin/python" make_data.py --only "${missing#,}")
fi
if [ ! -f "$DATA/results/ref-robust/${SCENES##*,}_shadow_OCCLUDED_occ.u8" ] || [ -n "$missing" ]; then
    echo "== Embree's per-ray results (embree_ref.py)"
    "$VENV/bin/python" "$HERE/embree_ref.py" "$DATA" --scenes "$SCENES"
fi

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
echo "== cargo build --release -p ember-tests --bin ember-bvh-embree"
(cd "$ROOT" && cargo build --release --quiet -p ember-tests --bin ember-bvh-embree)
BIN="$CARGO_TARGET_DIR/release/ember-bvh-embree"
# The same bench built for this CPU (AVX registers for the eight-wide BVH nodes, kernel/src/bvh/lanes.rs),
# as Embree picks its AVX2/AVX-512 kernels at run time. NATIVE_RUSTFLAGS="" skips it.
NATIVE_RUSTFLAGS="${NATIVE_RUSTFLAGS--C target-cpu=native}"
NBIN=""
if [ -n "$NATIVE_RUSTFLAGS" ]; then
    echo "== RUSTFLAGS=\"$NATIVE_RUSTFLAGS\" cargo build --release -p ember-tests --bin ember-bvh-embree"
    # A target folder per set of flags, so that switching them does not rebuild the other.
    ndir="$CARGO_TARGET_DIR-native"
    [ "$NATIVE_RUSTFLAGS" = "-C target-cpu=native" ] || ndir="$CARGO_TARGET_DIR-flags-$(echo "$NATIVE_RUSTFLAGS" | tr -c 'A-Za-z0-9.\n' '_')"
    (cd "$ROOT" && RUSTFLAGS="$NATIVE_RUSTFLAGS" cargo build --release --quiet -p ember-tests \
        --bin ember-bvh-embree --target-dir "$ndir")
    NBIN="$ndir/release/ember-bvh-embree"
fi

# Embree's ISA (EMBREE_ISA): the preloaded shim and what Embree reports with it.
embree_env=()
isa_note=""
if [ -n "$EMBREE_ISA" ]; then
    cc -O2 -shared -fPIC -o "$WORK/rtc_config.so" "$HERE/rtc_config.c" -ldl
    embree_env=(env LD_PRELOAD="$WORK/rtc_config.so" EMBER_EMBREE_CONFIG="isa=$EMBREE_ISA")
    targets="$(env LD_PRELOAD="$WORK/rtc_config.so" EMBER_EMBREE_CONFIG="isa=$EMBREE_ISA,verbose=1" \
        "$VENV/bin/python" -c 'import embreex.rtcore as r; r.EmbreeDevice()' 2>&1 \
        | sed -n 's/^ *Targets *: *\(.*\) (supported).*/\1/p' | tail -n 1 | sed 's/ *$//')"
    if [ "${targets##* }" != "${EMBREE_ISA^^}" ]; then
        echo "Embree did not take isa=$EMBREE_ISA (its targets: '$targets')" >&2
        exit 1
    fi
    isa_note="Embree's device config: \`isa=$EMBREE_ISA\` (EMBREE_ISA; its targets then: $targets), an $EMBREE_ISA machine's kernels on this CPU."
    echo "== $isa_note"
fi

# LOCKSTEP_ONLY=1: only the lockstep ratios below (about 20 minutes for all scenes).
if [ "${LOCKSTEP_ONLY:-0}" != 1 ]; then
    # One thread pinned to one CPU, as bench.py pins Embree's 1-thread runs.
    pin=()
    if command -v taskset >/dev/null; then
        pin=(taskset -c "$(taskset -pc $$ | sed 's/.*: *//; s/[-,].*//')")
    fi
    echo "== uptime: $(uptime)"
    # Interleaved: in each of ROUNDS rounds, every scene runs ember (portable, then native; 1 thread
    # pinned, then 2) and then Embree (bench.py for that scene alone: 1 thread, 2, robust), so that
    # both sides of a ratio are measured minutes apart and this instance's drift (10-30% within an
    # hour) falls on both. One process per scene, build and thread count, each well under 2 minutes.
    for f in ember-1t ember-2t ember-native-1t ember-native-2t; do : >"$RES/$f.jsonl"; : >"$RES/$f.txt"; done
    rm -rf "$RES/embree-rounds"; mkdir -p "$RES/embree-rounds"
    # What other processes take meanwhile (ember's binary also measures it itself, per row).
    python3 "$HERE/cpu_other.py" "$(ps -o pgid= $$ | tr -d ' ')" "$RES/embree-other-cpu.json" &
    sampler=$!
    for ((round = 0; round < ROUNDS; round++)); do
        for s in ${SCENES//,/ }; do
            for build in portable native; do
                bin="$BIN"; tag=""
                if [ "$build" = native ]; then
                    [ -n "$NBIN" ] || continue
                    bin="$NBIN"; tag="-native"
                fi
                for threads in 1 2; do
                    echo "== round $round: ember ($build build) $s, $threads thread(s)"
                    run=("$bin")
                    [ "$threads" = 1 ] && run=("${pin[@]}" "$bin")
                    "${run[@]}" "$DATA" --scenes "$s" --threads "$threads" --passes "$PASSES" \
                        --json "$RES/part.jsonl" | tee -a "$RES/ember$tag-${threads}t.txt"
                    # Each row tagged with its round (table.py pools the rounds' passes).
                    python3 -c 'import json, sys
for line in open(sys.argv[1]):
    if line.strip():
        r = json.loads(line); r["round"] = int(sys.argv[2]); print(json.dumps(r))' \
                        "$RES/part.jsonl" "$round" >>"$RES/ember$tag-${threads}t.jsonl"
                done
            done
            echo "== round $round: Embree $s (bench.py --skip-native --scenes $s --rounds 1)"
            (cd "$DATA" && "${embree_env[@]}" "$VENV/bin/python" bench.py --skip-native --scenes "$s" \
                --rounds 1 --reps "$PASSES")
            cp "$DATA/results/bench_results.json" "$RES/embree-rounds/$round-$s.json"
        done
    done
    rm -f "$RES/part.jsonl"
    kill "$sampler"; wait "$sampler" || true
    # One bench_results.json over all rounds and scenes, as one bench.py run would write it.
    python3 - "$RES/embree-rounds" "$DATA/results/bench_results.json" "$ROUNDS" <<'PY'
import glob, json, os, sys
# ROUND-SCENE.json, in round order (table.py pairs each round's ember and Embree medians).
parts = sorted(glob.glob(os.path.join(sys.argv[1], "*.json")),
               key=lambda p: int(os.path.basename(p).split("-", 1)[0]))
results, metas = [], []
for p in parts:
    d = json.load(open(p))
    rnd = int(os.path.basename(p).split("-", 1)[0])
    for r in d["results"]:
        r["round"] = rnd
    results += d["results"]
    metas.append(d["meta"])
meta = dict(metas[0])
meta["rounds"] = int(sys.argv[3])
meta["scenes"] = list(dict.fromkeys(s for m in metas for s in m["scenes"]))
meta["load_end"] = metas[-1].get("load_end", "?")
meta["total_s"] = sum(m.get("total_s", 0) for m in metas)
meta["interleaved"] = True
json.dump(dict(meta=meta, results=results), open(sys.argv[2], "w"), indent=1)
PY
    rm -rf "$RES/embree-rounds"
    (cd "$DATA" && "$VENV/bin/python" bench.py --report-only)
    cp "$DATA/results/bench_results.json" "$DATA/RESULTS.md" "$RES/"
    echo "== uptime: $(uptime)"
    native=()
    [ -n "$NBIN" ] && native=(--ember-native "$RES/ember-native-1t.jsonl" "$RES/ember-native-2t.jsonl"
        --native-flags "$NATIVE_RUSTFLAGS")
    "$VENV/bin/python" "$HERE/table.py" --data "$DATA" --ember "$RES/ember-1t.jsonl" "$RES/ember-2t.jsonl" \
        "${native[@]}" ${isa_note:+--note "$isa_note"} --out "$OUT/table.md"
fi

# Lockstep ratios (lockstep.py): per scene and thread count, LOCKSTEP_EPOCHS epochs of fresh
# processes (ember portable and native, Embree default and robust), each timing LOCKSTEP_ROUNDS
# rounds of one pass per side in turn, so that each pair of passes is seconds apart; a ratio is
# the median of the epochs' ratios with its 95% confidence interval. LOCKSTEP=0 skips it.
if [ "${LOCKSTEP:-1}" != 0 ]; then
    sides=(--ember "ember=$BIN")
    [ -n "$NBIN" ] && sides+=(--ember "ember-native=$NBIN")
    : >"$RES/lockstep.jsonl"
    {
        echo "# ember against Embree in lockstep ($(date -u '+%Y-%m-%d %H:%M') UTC)"
        echo
        echo "Generated by \`bench/embree/run.sh\` with \`bench/embree/lockstep.py\` (${LOCKSTEP_EPOCHS:-6} epochs x ${LOCKSTEP_ROUNDS:-4} rounds per row)${isa_note:+. $isa_note}"
        echo
    } >"$OUT/lockstep.md"
    IFS=, read -ra scene_list <<<"$SCENES"
    for threads in 1 2; do
        for s in "${scene_list[@]}"; do
            echo "== lockstep: $s, $threads thread(s)"
            "${embree_env[@]}" "$VENV/bin/python" "$HERE/lockstep.py" "$DATA" --scene "$s" \
                --threads "$threads" --epochs "${LOCKSTEP_EPOCHS:-6}" --rounds "${LOCKSTEP_ROUNDS:-4}" \
                "${sides[@]}" --embree --robust \
                --json "$RES/lockstep-part.jsonl" | tee -a "$OUT/lockstep.md"
            cat "$RES/lockstep-part.jsonl" >>"$RES/lockstep.jsonl"
            echo >>"$OUT/lockstep.md"
        done
    done
    rm -f "$RES/lockstep-part.jsonl"
fi
