#!/usr/bin/env bash
# Renders a scene as N shards in parallel on this machine (xargs -P), then merges them.
# The merged image is bit-identical to `ember render SCENE -o OUT` with the same options.
#
#   scripts/distributed/local.sh SCENE.toml N OUT.exr [ember render options...]
#   e.g. scripts/distributed/local.sh data/cornell-box/cornell_box.toml 4 /tmp/cb.exr --spp 64
#
# EMBER (default: `ember` on PATH, else the release build) names the binary; each shard runs
# with --threads 1 unless the options say otherwise, and JOBS (default N) shards run at once.
set -euo pipefail
scene=$1 n=$2 out=$3
shift 3
ember=${EMBER:-$(command -v ember || echo "${CARGO_TARGET_DIR:-$HOME/.cache/ember-target}/release/ember")}
parts_dir=$(mktemp -d "${TMPDIR:-/tmp}/ember-shards.XXXXXX")
trap 'rm -rf "$parts_dir"' EXIT
threads=(--threads 1)
for o in "$@"; do [ "$o" = --threads ] && threads=(); done
seq 0 $((n - 1)) | xargs -P "${JOBS:-$n}" -I{} \
    "$ember" render "$scene" --shard "{}/$n" -o "$parts_dir/part-{}.exr" -q "${threads[@]}" "$@"
"$ember" merge "$parts_dir"/part-*.exr -o "$out"
