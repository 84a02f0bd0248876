#!/usr/bin/env bash
# The GPU backend's speed on a machine with a GPU (issue 50): builds dfsph2d and prints one
# table of the viewer's dam break (the built-in scene, the paper's Jacobi solves) on
# `--backend gpu` at 5k, 20k, 80k, 320k and 1.28 M particles: particle-steps per second, ms
# per step, the real-time factor and the solves' iterations. Each size runs a short simulated
# interval, so the whole table takes a few minutes on a GPU.
#
#   scripts/gpu-bench.sh [OUT_DIR]        (rows also in OUT_DIR/gpu-bench.json)
#
# On a machine whose only Vulkan device is a software one (Mesa's lavapipe) it says so and
# stops: those times say nothing about a GPU. FORCE=1 runs it anyway (to check the script).
# The benchmark's own settings (docs/BENCHMARK.md) run on the device too: `dfsph2d bench
# --backend gpu` without `--realtime`.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-${TMPDIR:-/tmp}/dfsph2d-gpu-bench}"
mkdir -p "$out"
cargo build --release -p dfsph-app
bin="${CARGO_TARGET_DIR:-target}/release/dfsph2d"
# Which adapter `--backend gpu` takes, from a one-step run's note.
probe="$("$bin" run dam-break --backend gpu --until 0.001 --out "$out/probe" 2>&1 || true)"
if grep -q "software adapter" <<<"$probe" && [ "${FORCE:-0}" != 1 ]; then
  grep "note:\|error:" <<<"$probe" >&2 || true
  echo "gpu-bench: no hardware GPU here (only a software adapter): its times say nothing" \
       "about a GPU's speed; FORCE=1 runs it anyway" >&2
  exit 1
fi
grep "error:" <<<"$probe" >&2 && exit 1
files=()
# Simulated seconds per size: about a thousand steps at the smaller sizes, fewer above.
for case in 5k:0.5 20k:0.25 80k:0.1 320k:0.04 1m:0.02; do
  size="${case%%:*}"
  until="${case#*:}"
  "$bin" bench --realtime --backend gpu --sizes "$size" --until "$until" \
    --json "$out/$size.json" > /dev/null
  files+=("$out/$size.json")
done
# One table from all rows.
"$bin" bench --from-json "$(IFS=,; echo "${files[*]}")" --json "$out/gpu-bench.json"
