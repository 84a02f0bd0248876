#!/usr/bin/env bash
# Build the viewer as a self-contained static web site into OUTDIR:
#   index.html, dfsph_web.js (wasm-bindgen's loader) and dfsph_web_bg.wasm.
# Installs what it needs: the wasm32-unknown-unknown target and wasm-bindgen-cli at the
# version Cargo.lock pins (into ~/.cache/dfsph2d-tools; DFSPH2D_TOOLS overrides).
# Serve it locally and open http://127.0.0.1:8080/ :
#   python3 -m http.server --bind 127.0.0.1 --directory OUTDIR 8080
set -euo pipefail
out="${1:?usage: scripts/build-web.sh OUTDIR}"
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"

if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi

# The CLI must match the wasm-bindgen library the page is compiled against, exactly.
version="$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/[^0-9.]/, ""); print; exit }' Cargo.lock)"
tools="${DFSPH2D_TOOLS:-$HOME/.cache/dfsph2d-tools}"
bindgen="$tools/bin/wasm-bindgen"
if ! "$bindgen" --version 2>/dev/null | grep -qx "wasm-bindgen $version"; then
  echo "build-web: installing wasm-bindgen-cli $version into $tools (once; a few minutes)" >&2
  # Its own lock file first; where a registry mirror lacks a locked version, the newest it has.
  cargo install wasm-bindgen-cli --version "$version" --locked --root "$tools" --quiet ||
    cargo install wasm-bindgen-cli --version "$version" --root "$tools" --quiet
fi

# A target directory of its own: this script also runs from inside `cargo test`, which holds
# the lock on the workspace's.
target="${DFSPH2D_WEB_TARGET_DIR:-$HOME/.cache/dfsph2d-web-target}"
# The solver's lane kernels compile to 128-bit SIMD (simd128, every current browser has it)
# by .cargo/config.toml; a RUSTFLAGS of the caller's would replace that, so it is unset here.
env -u RUSTFLAGS -u CARGO_ENCODED_RUSTFLAGS \
  cargo build --profile web --locked -p dfsph-web --target wasm32-unknown-unknown \
  --target-dir "$target"

mkdir -p "$out"
"$bindgen" --target web --no-typescript --out-dir "$out" \
  "$target/wasm32-unknown-unknown/web/dfsph_web.wasm"
cp crates/dfsph-web/index.html "$out/index.html"

wasm="$out/dfsph_web_bg.wasm"
echo "build-web: $out (dfsph_web_bg.wasm: $(wc -c <"$wasm") bytes, $(gzip -9c "$wasm" | wc -c) gzipped)" >&2
