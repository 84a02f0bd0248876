#!/usr/bin/env bash
# The solver built serial (no rayon) for WebAssembly with simd128, tested under Node's WASI:
#  1. its whole test suite (tests of thread counts are compiled out; should_panic tests are
#     ignored, as WebAssembly aborts on a panic);
#  2. the same bits as natively: the fingerprint example on the portable path, the serial
#     and parallel native builds and the WebAssembly build must print the same lines.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v node >/dev/null; then
  echo "error: scripts/test-wasm.sh needs Node.js (node) to run WebAssembly" >&2
  exit 1
fi
rustup target add wasm32-wasip1 >/dev/null 2>&1 || true
export CARGO_TARGET_WASM32_WASIP1_RUNNER="node --no-warnings $PWD/scripts/wasi-run.mjs"

cargo test -p dfsph --release --no-default-features --target wasm32-wasip1

fingerprints() {
  cargo run -q --release -p dfsph --example fingerprint "$@"
}
parallel=$(DFSPH2D_SIMD=portable fingerprints)
serial=$(DFSPH2D_SIMD=portable fingerprints --no-default-features)
wasm=$(fingerprints --no-default-features --target wasm32-wasip1)
echo "$parallel"
if [[ "$serial" != "$parallel" || "$wasm" != "$parallel" ]]; then
  echo "error: the builds computed different bits" >&2
  diff <(echo "$parallel") <(echo "$serial") >&2 || true
  diff <(echo "$parallel") <(echo "$wasm") >&2 || true
  exit 1
fi
echo "parallel, serial and WebAssembly builds: the same bits on the portable path"
