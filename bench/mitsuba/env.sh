# Shared setup of the Mitsuba scripts (sourced by run.sh and materials.sh): a virtual
# environment bench/venv with Mitsuba 3 and numpy from PyPI (~300 MB installed), LLVM 19 for
# the llvm_ad_* variants (Debian's libllvm19, found through DRJIT_LIBLLVM_PATH) unless
# NEED_LLVM=0, and a release build of ember unless NEED_EMBER=0 (and one for this CPU with
# EMBER_NATIVE=1). Sets VENV, ROOT, EMBER, EMBER_NATIVE_BIN.
: "${HERE:?set HERE to bench/mitsuba before sourcing env.sh}"
ROOT="$(cd "$HERE/../.." && pwd)"
VENV="$ROOT/bench/venv"

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
if [ "${NEED_LLVM:-1}" != 0 ] && [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
    if [ -z "$(find /usr/lib -name 'libLLVM-19*.so*' 2>/dev/null | head -n 1)" ]; then
        echo "== apt-get install libllvm19"
        if [ "$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libllvm19 >/dev/null
    fi
    DRJIT_LIBLLVM_PATH="$(find /usr/lib -name 'libLLVM-19*.so*' 2>/dev/null | sort | head -n 1)"
    [ -n "$DRJIT_LIBLLVM_PATH" ] || DRJIT_LIBLLVM_PATH="$(find_llvm)"
    export DRJIT_LIBLLVM_PATH
    echo "== DRJIT_LIBLLVM_PATH=$DRJIT_LIBLLVM_PATH"
fi

# ember, optimised (unless NEED_EMBER=0).
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
EMBER="$CARGO_TARGET_DIR/release/ember"
if [ "${NEED_EMBER:-1}" != 0 ]; then
    echo "== cargo build --release -p ember-cli"
    (cd "$ROOT" && cargo build --release --quiet -p ember-cli --bin ember)
fi
# With EMBER_NATIVE=1, also ember built for this CPU (-C target-cpu=native: the same images,
# bench/determinism-cost), as EMBER_NATIVE_BIN; EMBER_NATIVE_CPU=x86-64-v3 builds it for AVX2
# instead (the counterpart of MITSUBA_LLVM_TARGET=avx2), in a target folder of its own.
EMBER_NATIVE_BIN=""
EMBER_NATIVE_CPU="${EMBER_NATIVE_CPU:-native}"
if [ "${EMBER_NATIVE:-0}" = 1 ]; then
    dir="$CARGO_TARGET_DIR/native"
    [ "$EMBER_NATIVE_CPU" = native ] || dir="$CARGO_TARGET_DIR/cpu-$EMBER_NATIVE_CPU"
    echo "== cargo build --release -p ember-cli (-C target-cpu=$EMBER_NATIVE_CPU)"
    (cd "$ROOT" && RUSTFLAGS="-C target-cpu=$EMBER_NATIVE_CPU" CARGO_TARGET_DIR="$dir" \
        cargo build --release --quiet -p ember-cli --bin ember)
    EMBER_NATIVE_BIN="$dir/release/ember"
fi
