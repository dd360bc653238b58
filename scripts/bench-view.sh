#!/usr/bin/env bash
# Responsiveness of ember-view's path-traced view, and what the view costs against
# `ember render`: the Cornell box in a real window under Xvfb (lavapipe without a GPU).
#
#   scripts/bench-view.sh [WIDTH HEIGHT [DRAG_SECONDS [STILL_SECONDS]]]     (default 800 600 4 30)
#
# Prints the CPU line and load, ember-view's closing summary (camera change → a frame of that
# view or a later one on screen, new frames per second while moving, samples/s once still, time
# for the rendering threads to stop), how fast a key press reaches the title while passes
# render, and `ember render`'s samples/s for the same film, integrator and seed. Needs xvfb and xdotool
# (scripts/test.sh installs them). A benchmark, not a test: nothing here passes or fails.
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-800}; H=${2:-600}; DRAG=${3:-4}; STILL=${4:-30}
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

# `ember render`'s samples/s for the same film, integrator and seed, before and after the view
# (the machine's load changes; the view's figure is between the two).
# Besides wall-clock samples/s, samples per CPU-second (user + system time of the process):
# the machine is shared, and CPU time is what the view costs whatever the other load.
ember_render() {
    local out cpu
    out=$(mktemp -d)
    TIMEFORMAT='%U %S'
    cpu=$( { time "$BIN/ember" render "$SCENE" --width "$W" --height "$H" --spp 16 -q -o "$out/r.exr" \
        2>"$out/log"; } 2>&1 )
    echo "ember render (16 spp): $(grep 'samples/s' "$out/log" | sed 's/^ember: //');" \
        "$(echo "$cpu" | awk -v n=$((W * H * 16)) '{printf "%.3f M samples per CPU-second (%.1f CPU-s)", n / ($1 + $2) / 1e6, $1 + $2}')"
    rm -rf "$out"
}
# User + system CPU seconds of a process so far.
cpu_seconds() { awk -v hz="$(getconf CLK_TCK)" '{printf "%.2f", ($14 + $15) / hz}' "/proc/$1/stat"; }
spp_of() { xdotool getwindowname "$WIN" | grep -o '[0-9]*/[0-9]* spp' | cut -d/ -f1; }
ember_render

LOG=$(mktemp)
"$BIN/ember-view" "$SCENE" --width "$W" --height "$H" --spp 100000 2>"$LOG" &
VPID=$!
trap 'kill "$VPID" "$XPID" 2>/dev/null || true' EXIT
until WIN=$(xdotool search --name '^ember-view' 2>/dev/null | head -1) && [ -n "$WIN" ]; do sleep 0.1; done
# Focus once and let the viewer see it (a key sent with the first focus change is dropped).
xdotool windowfocus --sync "$WIN"; sleep 0.3
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
sleep 2
s0=$(spp_of); c0=$(cpu_seconds "$VPID"); t0=$(date +%s%N)
sleep "$STILL"
s1=$(spp_of); c1=$(cpu_seconds "$VPID"); t1=$(date +%s%N)
echo "title after $((STILL + 2)) s still: $(xdotool getwindowname "$WIN")"
awk -v s0="$s0" -v s1="$s1" -v c0="$c0" -v c1="$c1" -v t0="$t0" -v t1="$t1" -v px=$((W * H)) 'BEGIN {
    n = (s1 - s0) * px
    printf "ember-view still, %d -> %d spp: %.3f M samples/s wall, %.3f M samples per CPU-second (%.1f CPU-s in %.1f s)\n",
        s0, s1, n / ((t1 - t0) / 1e9) / 1e6, n / (c1 - c0) / 1e6, c1 - c0, (t1 - t0) / 1e9 }'
# The event loop while passes render: a key press (exposure) until the title shows it, 5 times.
for i in 1 2 3 4 5; do
    key=$([ $((i % 2)) = 1 ] && echo bracketright || echo bracketleft)
    t0=$(date +%s%N)
    xdotool key "$key"
    seen=no
    for _ in $(seq 1 2000); do   # at most ~10 s
        title=$(xdotool getwindowname "$WIN")
        if { [ "$key" = bracketright ] && [[ "$title" == *"exposure +0.5"* ]]; } ||
           { [ "$key" = bracketleft ] && [[ "$title" != *exposure* ]]; }; then
            seen=yes; break
        fi
        sleep 0.002
    done
    echo "key $key -> title updated: $seen, in $(( ($(date +%s%N) - t0) / 1000000 )) ms (xdotool included)"
    sleep 0.7
done
xdotool key Escape
wait "$VPID"
grep -E 'camera changes|stopped' "$LOG" | sed 's/^/ember-view: /; s/^ember-view: ember-view: /ember-view: /'
rm -f "$LOG"

ember_render   # after the view, as before it
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
