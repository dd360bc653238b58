#!/usr/bin/env bash
# What the determinism rules cost: the same renders from three builds of `ember`, timed in one
# run on one machine (alternating, medians of RUNS):
#   det     the shipped build (baseline x86-64 or the host's default target; no fused
#           multiply-add, glam's SIMD types banned from the kernel, every image bit-identical
#           across targets);
#   native  -C target-cpu=native: the compiler may use every instruction this CPU has
#           (AVX2, AVX-512) but still never fuses a multiply and an add, so images stay
#           bit-identical (scripts/determinism.sh checks x86-64-v3);
#   fma     native plus -C llvm-args=-fp-contract=fast: LLVM fuses multiplies and adds
#           wherever it likes, which the rules forbid (the images then depend on the target).
# The cost of the no-FMA rule is fma against native; of the baseline target, native against
# det. glam's SIMD types (Vec3A, Vec4 dot products) would need source changes and are not
# measured here. Prints the CPU model and its SIMD flags, and whether each image is
# bit-identical to det's (with `ember compare` against it when not). Writes the table to
# bench/determinism-cost/table.md as well.
# Usage: bench/determinism-cost/run.sh [RUNS]
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
RUNS="${1:-3}"
TINYRENDER="${EMBER_TINYRENDER:-$ROOT/../shared/tinyrender}"
base="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT

exec > >(tee "$HERE/table.md")
echo "# The determinism rules' cost ($(date -u '+%Y-%m-%d %H:%M') UTC, $RUNS alternating runs, medians; 320x240, $(nproc) threads)"
echo
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) threads"
echo
echo "SIMD: $(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -xE 'sse4_2|avx|avx2|fma|avx512f|avx512dq|avx512bw|avx512vl|neon' | tr '\n' ' ')"

declare -A flags=(
    [det]=""
    [native]="-C target-cpu=native"
    [fma]="-C target-cpu=native -C llvm-args=-fp-contract=fast"
)
variants=(det native fma)
for v in "${variants[@]}"; do
    dir="$base"
    [ "$v" = det ] || dir="$base/determinism-cost-$v"
    RUSTFLAGS="${flags[$v]}" CARGO_TARGET_DIR="$dir" \
        cargo build --release -q -p ember-cli --bin ember --manifest-path "$ROOT/Cargo.toml"
    cp "$dir/release/ember" "$out/ember-$v"
done

# name | scene | options
scenes=(
    "cornell-box mis|$ROOT/data/cornell-box/cornell_box.toml|--integrator mis --spp 64"
    "cbox.obj mis|$TINYRENDER/data/a5/cbox/tinyrender/cbox_path_explicit_rr.toml|--integrator mis --spp 32"
    "cbox.obj bdpt|$TINYRENDER/data/a5/cbox/tinyrender/cbox_path_explicit_rr.toml|--integrator bdpt --spp 8"
)
printf '\n| scene | det s | native s | fma s | native/det | fma/native | fma image |\n|---|---|---|---|---|---|---|\n'
for entry in "${scenes[@]}"; do
    IFS='|' read -r name scene opts <<<"$entry"
    declare -A times=()
    for v in "${variants[@]}"; do times[$v]=""; done
    for _ in $(seq "$RUNS"); do
        for v in "${variants[@]}"; do
            # shellcheck disable=SC2086
            s=$("$out/ember-$v" render "$scene" $opts --width 320 --height 240 --threads "$(nproc)" \
                -q -o "$out/$v.exr" 2>&1 | sed -n 's/^ember: \([0-9.]*\) s,.*/\1/p')
            times[$v]="${times[$v]} $s"
        done
    done
    median() { tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
    det=$(median <<<"${times[det]}")
    native=$(median <<<"${times[native]}")
    fma=$(median <<<"${times[fma]}")
    if cmp -s "$out/det.exr" "$out/native.exr"; then native_same=yes; else native_same=NO; fi
    if cmp -s "$out/det.exr" "$out/fma.exr"; then
        fma_image="bit-identical"
    else
        cmp_out=$("$out/ember-det" compare "$out/fma.exr" "$out/det.exr" 2>&1 | tr -s '\n ' '  ')
        fma_image="differs: rmse $(sed -n 's/.* rmse \([^ ]*\).*/\1/p' <<<"$cmp_out"), max_abs $(sed -n 's/.* max_abs \([^ ]*\).*/\1/p' <<<"$cmp_out")"
    fi
    ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a / b }'; }
    printf '| %s | %s | %s | %s | %s | %s | %s |\n' "$name" "$det" "$native" "$fma" \
        "$(ratio "$native" "$det")" "$(ratio "$fma" "$native")" "$fma_image"
    [ "$native_same" = yes ] || echo "warning: the native build's image of $name differs from det's" >&2
done
