#!/usr/bin/env bash
# Runs ember's whole test suite on a fresh machine: installs what the tests need, checks
# formatting and lints, then runs every test (slow statistical ones included) in release mode.
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
export EMBER_TINYRENDER="${EMBER_TINYRENDER:-$PWD/../shared/tinyrender}"
export CARGO_TERM_COLOR=never

# The reference scenes are read at test time, never copied into the project.
if [ ! -d "$EMBER_TINYRENDER/data/a5/cbox/tinyrender" ]; then
    echo "error: TinyRender data not found at $EMBER_TINYRENDER (set EMBER_TINYRENDER)" >&2
    exit 1
fi

# A software GPU for the headless wgpu tests (Mesa's lavapipe Vulkan driver; EGL/llvmpipe as
# a fallback), and for the viewer's window tests (host-viewer/tests/window.rs) an X server
# without a screen (xvfb), synthetic input and window titles (xdotool) and window screenshots
# (imagemagick's `import`). A missing adapter or tool fails those tests; they never skip.
need=()
for pkg in mesa-vulkan-drivers libegl1 libgl1-mesa-dri xvfb xdotool imagemagick; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
    echo "== installing ${need[*]}"
    if [ "$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need[@]}" >/dev/null
fi

# Rust components the checks use (present on the project's machines; installed if not).
if command -v rustup >/dev/null 2>&1; then
    rustup component list --installed 2>/dev/null | grep -q '^rustfmt' || rustup component add rustfmt
    rustup component list --installed 2>/dev/null | grep -q '^clippy' || rustup component add clippy
fi

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy"
cargo clippy --workspace --all-targets --release -- -D warnings
echo "== cargo test (release: the statistical tests run too)"
cargo test --workspace --release
echo "== the AVX lanes of the shipped binary and the C API are inlined (no x86 intrinsic as a function)"
# An intrinsic that LLVM leaves out of its AVX function (a closure not inlined into
# `Avx::run`'s function) becomes a call per lane operation: _mm256_mul_ps as a function cost
# a batched render 11% (2026-12-07). The portable build compiles AVX code only in those
# functions, so any SSE/AVX intrinsic symbol in `ember` is such a call.
# The C API's static library is checked the same way: embedders get its lanes.
cargo build --release -p ember-cli --bin ember
cargo build --release -p ember-capi
for artefact in ember libember_capi.a; do
    symbols="$(nm -C "$CARGO_TARGET_DIR/release/$artefact" 2>/dev/null)"
    if grep -E 'core_arch::x86::(sse[0-9a-z]*|avx[0-9a-z]*|fma)::_mm' <<<"$symbols"; then
        echo "error: x86 intrinsics left out of line in release/$artefact (above)" >&2
        exit 1
    fi
done
echo "== determinism across builds and targets (scripts/determinism.sh)"
./scripts/determinism.sh
echo "== the kernel built for AVX and for aarch64 (kernel/src/bvh/lanes.rs): clippy, unit, BVH and stress suites"
# The default build's eight-wide nodes are tested in SSE register pairs; here their AVX
# encoding, and the four-wide tree of every target but x86-64 (NEON, under qemu-user as in
# determinism.sh, which installed it). Same flags and target directory as determinism.sh's
# x86-64-v3 build; a CPU without AVX2 runs the tests on qemu's emulated one.
v3=(--release -p ember-kernel --target-dir "$CARGO_TARGET_DIR/determinism/x86-64-v3")
runner=()
grep -qw avx2 /proc/cpuinfo || runner=(--config 'target.x86_64-unknown-linux-gnu.runner="qemu-x86_64-static -cpu max"')
RUSTFLAGS="-C target-cpu=x86-64-v3" cargo clippy "${v3[@]}" --all-targets -- -D warnings
RUSTFLAGS="-C target-cpu=x86-64-v3" cargo test "${v3[@]}" "${runner[@]}" --lib --test bvh --test stress
CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc \
    cargo test --release -p ember-kernel --target aarch64-unknown-linux-gnu \
    --config 'target.aarch64-unknown-linux-gnu.runner="qemu-aarch64-static -L /usr/aarch64-linux-gnu"' \
    --lib --test bvh --test stress
