#!/usr/bin/env bash
# Coverage-guided fuzzing of the scene loaders with cargo-fuzz (README.md, "Fuzzing").
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]     (default: 300 s; scene_toml obj obj_mtl)
#
# Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`). Each target starts from
# the committed corpus (tests/fuzz-corpus/<target>/) plus whatever earlier runs left in
# host-cli/fuzz/corpus/<target>/, runs one libFuzzer process for the given time, and prints the
# executions; a crash stops the target and is written to host-cli/fuzz/artifacts/<target>/.
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
seconds="${1:-300}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene_toml obj obj_mtl)

command -v cargo-fuzz >/dev/null || { echo "error: cargo-fuzz not found (cargo install cargo-fuzz)" >&2; exit 1; }

status=0
for t in "${targets[@]}"; do
    case "$t" in
        scene_toml) dict=toml.dict; max_len=4096 ;;
        obj | obj_mtl) dict=obj.dict; max_len=8192 ;;
        *) echo "error: unknown target $t (scene_toml, obj, obj_mtl)" >&2; exit 2 ;;
    esac
    work="host-cli/fuzz/corpus/$t"
    mkdir -p "$work" "host-cli/fuzz/artifacts/$t"
    cp -n tests/fuzz-corpus/"$t"/* "$work"/ 2>/dev/null || true
    echo "== $t: ${seconds} s"
    log="host-cli/fuzz/artifacts/$t/last-run.log"
    # -rss_limit_mb and -malloc_limit_mb turn unbounded allocation into a reported failure,
    # -timeout a hang; -max_len bounds the inputs (the largest seed is 5.6 KB).
    if (cd host-cli && cargo +nightly fuzz run "$t" "fuzz/corpus/$t" -- \
            -dict="fuzz/dicts/$dict" -max_len="$max_len" -rss_limit_mb=2048 \
            -malloc_limit_mb=2048 -timeout=5 -max_total_time="$seconds" \
            -print_final_stats=1) >"$log" 2>&1; then
        grep -E '^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)' "$log"
    else
        status=1
        grep -E 'panicked at|ERROR: libFuzzer|Test unit written' "$log" || tail -20 "$log"
    fi
done
exit $status
