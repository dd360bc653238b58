#!/usr/bin/env bash
# Responsiveness of ember-view's path-traced view, and what the view costs against
# `ember render`: the Cornell box in a real window under Xvfb (lavapipe without a GPU).
#
#   scripts/bench-view.sh [WIDTH HEIGHT [DRAG_SECONDS [STILL_SECONDS]]]     (default 800 600 4 20)
#
# Prints the CPU line and load, ember-view's closing summary (camera change → a frame of that
# view or a later one on screen, new frames per second while moving, samples/s once still, time
# for the rendering threads to stop), how fast a key press reaches the title while passes
# render, and `ember render`'s samples/s for the same film, integrator and seed. Needs xvfb and xdotool
# (scripts/test.sh installs them). A benchmark, not a test: nothing here passes or fails.
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-800}; H=${2:-600}; DRAG=${3:-4}; STILL=${4:-20}
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}"
cargo build --release -q -p ember-cli -p ember-viewer
BIN="$CARGO_TARGET_DIR/release"
SCENE=data/cornell-box/cornell_box.toml

echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc) cores;" \
     "SIMD: $(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -E '^(sse|ssse|avx|fma)' | sort -u | tr '\n' ' ')"

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
exec 3< <(Xvfb -displayfd 1 -screen 0 1280x1024x24 -nolisten tcp 2>/dev/null & echo "pid $!")
read -r _ XPID <&3
read -r N <&3
export DISPLAY=":$N"
trap 'kill "$XPID" 2>/dev/null || true' EXIT
until xdotool getdisplaygeometry >/dev/null 2>&1; do sleep 0.05; done

LOG=$(mktemp)
"$BIN/ember-view" "$SCENE" --width "$W" --height "$H" --spp 100000 2>"$LOG" &
VPID=$!
until WIN=$(xdotool search --name '^ember-view' 2>/dev/null | head -1) && [ -n "$WIN" ]; do sleep 0.1; done
sleep 3   # first passes
# A drag: 50 mouse moves a second for DRAG seconds, back and forth.
steps=$((DRAG * 50))
xdotool mousemove --window "$WIN" $((W / 2)) $((H / 2)) mousedown 1
for i in $(seq 1 "$steps"); do
    dx=$(( (i % 100 < 50) ? 4 : -4 ))
    xdotool mousemove_relative -- "$dx" 0
    sleep 0.02
done
xdotool mouseup 1
sleep "$STILL"
echo "title after ${STILL} s still: $(xdotool getwindowname "$WIN")"
# The event loop while passes render: a key press (exposure) until the title shows it, 5 times.
for i in 1 2 3 4 5; do
    key=$([ $((i % 2)) = 1 ] && echo bracketright || echo bracketleft)
    t0=$(date +%s%N)
    xdotool windowfocus "$WIN" key "$key"
    if [ "$key" = bracketright ]; then
        until xdotool getwindowname "$WIN" | grep -q 'exposure +0.5'; do sleep 0.002; done
    else
        while xdotool getwindowname "$WIN" | grep -q 'exposure'; do sleep 0.002; done
    fi
    echo "key $key -> title updated in $(( ($(date +%s%N) - t0) / 1000000 )) ms (xdotool included)"
    sleep 0.7
done
xdotool windowfocus "$WIN" key Escape
wait "$VPID"
grep -E 'camera changes|stopped' "$LOG" | sed 's/^/ember-view: /; s/^ember-view: ember-view: /ember-view: /'
rm -f "$LOG"

SPP=16
OUT=$(mktemp -d)
"$BIN/ember" render "$SCENE" --width "$W" --height "$H" --spp "$SPP" -q -o "$OUT/r.exr" 2>&1 | grep 'samples/s' | sed 's/^/ember render ('"$SPP"' spp): /'
rm -rf "$OUT"
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
