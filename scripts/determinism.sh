#!/usr/bin/env bash
# Renders ember's determinism scene (tests/determinism: a Cornell box in arrays, every BSDF,
# every path integrator, the light tracer and BDPT with their splats, a bake) in every build
# configuration and on every target, prints a table of the hashes of the pixel bits (render:
# path tracers, bake, splat: light tracer and BDPT), and exits non-zero unless all of them equal
# the golden hashes in tests/golden/determinism.txt:
#
#   host debug (kernel at opt-level 3, as the dev profile has it, and at opt-level 0),
#   host release with 1, 2 and 7 threads taking rows and with 7 threads taking 5x5 tiles (each
#   thread with its own splat buffer), with the ray queries limited to the baseline lanes (no
#   run-time AVX2), -C target-cpu=x86-64 and -C target-cpu=x86-64-v3
#   (AVX2 and FMA), aarch64-unknown-linux-gnu under qemu-user, wasm32-unknown-unknown under
#   Node.js, x86_64-unknown-none (no std, no alloc, soft float; linked into a C program), and
#   the C API (libember_capi.a + tests/capi/cornell.c rendering from two pthreads, a splat
#   buffer each, merged with ember_splat_merge).
#
# Installs what it needs when it is missing: the rustup targets, Debian's gcc-aarch64-linux-gnu
# and qemu-user-static, a C compiler and Node.js. Builds that need their own RUSTFLAGS or
# profile settings use subfolders of the target directory so they never invalidate the main
# build cache.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
start=$(date +%s)

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
export CARGO_TERM_COLOR=never
target="$CARGO_TARGET_DIR"
alt="$target/determinism"  # builds with their own flags
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

say() { echo "== $*" >&2; }

# --- what the configurations need ------------------------------------------------------------
if [ "$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi
need=()
command -v aarch64-linux-gnu-gcc >/dev/null || need+=(gcc-aarch64-linux-gnu libc6-dev-arm64-cross)
command -v qemu-aarch64-static >/dev/null || need+=(qemu-user-static)
command -v cc >/dev/null || need+=(gcc libc6-dev)
command -v node >/dev/null || need+=(nodejs)
if [ ${#need[@]} -gt 0 ]; then
    say "installing ${need[*]}"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
        "${need[@]}" >/dev/null
fi
targets=(aarch64-unknown-linux-gnu wasm32-unknown-unknown x86_64-unknown-none)
installed=$(rustup target list --installed)
for t in "${targets[@]}"; do
    if ! grep -qx "$t" <<<"$installed"; then
        say "rustup target add $t"
        rustup target add "$t"
    fi
done

# --- the configurations ----------------------------------------------------------------------
names=()
renders=()
bakes=()
splats=()

# record NAME OUTPUT: keeps the `render`, `bake` and `splat` hashes a configuration printed.
record() {
    local r b s
    r=$(awk '$1 == "render" { print $2 }' <<<"$2")
    b=$(awk '$1 == "bake" { print $2 }' <<<"$2")
    s=$(awk '$1 == "splat" { print $2 }' <<<"$2")
    names+=("$1")
    renders+=("${r:-missing}")
    bakes+=("${b:-missing}")
    splats+=("${s:-missing}")
}

det=(-p ember-determinism --bin ember-determinism --quiet)

say "host debug"
cargo build "${det[@]}"
record "host debug (dev profile: kernel opt-level 3)" "$("$target/debug/ember-determinism")"

say "host debug, kernel at opt-level 0"
cargo build "${det[@]}" --target-dir "$alt/opt0" \
    --config 'profile.dev.package.ember-kernel.opt-level=0'
record "host debug, kernel opt-level 0" "$("$alt/opt0/debug/ember-determinism")"

say "host release"
cargo build "${det[@]}" --release
for n in 1 2 7; do
    record "host release, $n thread(s)" "$("$target/release/ember-determinism" --threads "$n")"
done
record "host release, 7 threads, 5x5 tiles" \
    "$("$target/release/ember-determinism" --threads 7 --tile 5)"
# The ray queries run with AVX-512 or AVX2 where the CPU has it (kernel/src/simd.rs); these
# rows run the AVX2 lanes (eight, one triangle group at a time) and the baseline (SSE2) lanes
# on such a CPU too.
record "host release, at most AVX2 ray-query lanes, 2 threads" \
    "$("$target/release/ember-determinism" --threads 2 --simd avx2)"
record "host release, baseline ray-query lanes only, 2 threads" \
    "$("$target/release/ember-determinism" --threads 2 --simd baseline)"

for cpu in x86-64 x86-64-v3; do
    say "host release, -C target-cpu=$cpu"
    RUSTFLAGS="-C target-cpu=$cpu" cargo build "${det[@]}" --release --target-dir "$alt/$cpu"
    bin="$alt/$cpu/release/ember-determinism"
    if [ "$cpu" = x86-64-v3 ] && ! grep -qw avx2 /proc/cpuinfo; then
        # This CPU cannot run AVX2 code: run it on qemu's emulated CPU instead.
        record "host release, target-cpu=$cpu (qemu -cpu max)" \
            "$(qemu-x86_64-static -cpu max "$bin" --threads 2)"
    else
        record "host release, target-cpu=$cpu, 2 threads" "$("$bin" --threads 2)"
    fi
done

say "aarch64-unknown-linux-gnu"
CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc \
    cargo build "${det[@]}" --release --target aarch64-unknown-linux-gnu
record "aarch64 release (qemu-aarch64), 2 threads" \
    "$(qemu-aarch64-static -L /usr/aarch64-linux-gnu \
        "$target/aarch64-unknown-linux-gnu/release/ember-determinism" --threads 2)"

say "wasm32-unknown-unknown"
cargo build -p ember-determinism-wasm --quiet --release --target wasm32-unknown-unknown
record "wasm32 release (Node.js $(node --version))" "$(node -e '
const fs = require("fs");
const wasm = new WebAssembly.Instance(new WebAssembly.Module(fs.readFileSync(process.argv[1])), {});
const hex = (v) => BigInt.asUintN(64, v).toString(16).padStart(16, "0");
console.log("render " + hex(wasm.exports.ember_render_hash()));
console.log("bake " + hex(wasm.exports.ember_bake_hash()));
console.log("splat " + hex(wasm.exports.ember_splat_hash()));
' "$target/wasm32-unknown-unknown/release/ember_determinism_wasm.wasm")"

say "x86_64-unknown-none (no std, no alloc)"
cargo build -p ember-no-std-check --quiet --release --target x86_64-unknown-none
cat >"$work/nostd.c" <<'EOF'
#include <stdint.h>
#include <stdio.h>
uint64_t ember_nostd_render_hash(void);
uint64_t ember_nostd_bake_hash(void);
uint64_t ember_nostd_splat_hash(void);
int main(void) {
    printf("render %016llx\nbake %016llx\nsplat %016llx\n",
           (unsigned long long)ember_nostd_render_hash(),
           (unsigned long long)ember_nostd_bake_hash(),
           (unsigned long long)ember_nostd_splat_hash());
    return 0;
}
EOF
cc -O2 -o "$work/nostd" "$work/nostd.c" "$target/x86_64-unknown-none/release/libember_no_std_check.a"
record "x86_64-unknown-none release (soft float), in C" "$("$work/nostd")"

say "C API"
cargo build -p ember-capi --quiet --release
cc -std=c11 -O2 -Wall -Wextra -Wpedantic -Werror -pthread -I kernel/include \
    tests/capi/cornell.c "$target/release/libember_capi.a" -lpthread -ldl -lm -o "$work/cornell"
record "C API release (cc, 2 pthreads, 8x8 tiles)" "$("$work/cornell")"

# --- the table -------------------------------------------------------------------------------
golden_render=$(awk '$1 == "render" { print $2 }' tests/golden/determinism.txt)
golden_bake=$(awk '$1 == "bake" { print $2 }' tests/golden/determinism.txt)
golden_splat=$(awk '$1 == "splat" { print $2 }' tests/golden/determinism.txt)
status=0
echo
row() { printf '%-52s  %-16s  %-16s  %-16s  %s\n' "$@"; }
row "configuration" "render" "bake" "splat" ""
row "golden (tests/golden/determinism.txt)" "$golden_render" "$golden_bake" "$golden_splat" ""
for i in "${!names[@]}"; do
    mark="ok"
    if [ "${renders[$i]}" != "$golden_render" ] || [ "${bakes[$i]}" != "$golden_bake" ] ||
        [ "${splats[$i]}" != "$golden_splat" ]; then
        mark="MISMATCH"
        status=1
    fi
    row "${names[$i]}" "${renders[$i]}" "${bakes[$i]}" "${splats[$i]}" "$mark"
done
echo
agree=1
for i in "${!names[@]}"; do
    if [ "${renders[$i]}" != "${renders[0]}" ] || [ "${bakes[$i]}" != "${bakes[0]}" ] ||
        [ "${splats[$i]}" != "${splats[0]}" ]; then
        agree=0
    fi
done
if [ $status = 0 ]; then
    echo "determinism: all ${#names[@]} configurations match the golden hashes ($(($(date +%s) - start)) s)"
elif [ $agree = 1 ]; then
    echo "determinism: FAILED: every configuration agrees, but not with the golden hashes." \
        "If the images changed on purpose, put the new hashes in tests/golden/determinism.txt" \
        "in the same commit and say why in its message."
else
    echo "determinism: FAILED: configurations disagree (see MISMATCH above)"
fi
exit $status
