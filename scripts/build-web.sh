#!/usr/bin/env bash
# Build the viewer as a self-contained static web site into OUTDIR:
#   index.html, dfsph_web.js (wasm-bindgen's loader) and dfsph_web_bg.wasm: single-threaded;
#   threads/: the same with WebAssembly threads (dfsph-web's `threads` feature: the solver
#   parallel on a pool of Web Workers), which index.html loads where the page is
#   cross-origin isolated. It needs the nightly toolchain with rust-src (std is rebuilt with
#   atomics); without them it is skipped, with a note, and the page stays single-threaded.
# Installs what it needs: the wasm32-unknown-unknown target and wasm-bindgen-cli at the
# version Cargo.lock pins (into ~/.cache/dfsph2d-tools; DFSPH2D_TOOLS overrides).
# Serve it locally with the headers threads need, and open http://127.0.0.1:8080/ :
#   scripts/serve-web.py OUTDIR 8080
# (any static server works too; without the headers the page runs single-threaded).
# DFSPH2D_WEB_THREADS=0 skips the threaded build.
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
  echo "build-web: installing wasm-bindgen-cli $version into $tools (once; 2-3 minutes on 2 cores)" >&2
  # Its own lock file first; where a registry mirror lacks a locked version, the newest it
  # has. cargo's refusal of the first is kept back: it says "error:" for what is a fallback,
  # and is shown only if the second attempt fails too.
  if ! locked="$(cargo install wasm-bindgen-cli --version "$version" --locked --root "$tools" --quiet 2>&1)"; then
    echo "build-web: wasm-bindgen-cli's lock file names versions this registry does not serve; installing it with the newest versions it has" >&2
    if ! cargo install wasm-bindgen-cli --version "$version" --root "$tools" --quiet; then
      echo "build-web: the install with its lock file had failed too:" >&2
      echo "$locked" >&2
      exit 1
    fi
  fi
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

# The threaded build: std rebuilt with atomics (-Z build-std, nightly), a target directory
# of its own (other flags), wasm-bindgen-rayon's pool. The module's memory must be shared
# (imported, with a maximum: 2 GiB) and export its thread-local storage for wasm-bindgen's
# thread support; those are link arguments, given to the last crate only (`cargo rustc`), so
# that changing them relinks without rebuilding everything.
rm -rf "$out/threads"
if [ "${DFSPH2D_WEB_THREADS:-1}" = 0 ]; then
  echo "build-web: threaded build skipped (DFSPH2D_WEB_THREADS=0): single-threaded only" >&2
  exit 0
fi
nightly="${DFSPH2D_NIGHTLY:-nightly}"
skip() {
  echo "build-web: NOTE: threaded build skipped ($1); the site is single-threaded only" >&2
  exit 0
}
rustup run "$nightly" rustc --version >/dev/null 2>&1 || skip "no $nightly toolchain: rustup toolchain install $nightly"
sysroot="$(rustup run "$nightly" rustc --print sysroot)"
[ -d "$sysroot/lib/rustlib/src/rust/library" ] ||
  skip "no rust-src for $nightly: rustup component add rust-src --toolchain $nightly"
if ! rustup target list --installed --toolchain "$nightly" 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown --toolchain "$nightly" ||
    skip "no wasm32-unknown-unknown target for $nightly"
fi
env -u CARGO_ENCODED_RUSTFLAGS \
  RUSTFLAGS="-C target-feature=+atomics,+bulk-memory,+mutable-globals,+simd128" \
  rustup run "$nightly" cargo rustc -Z build-std=panic_abort,std \
  --profile web --locked -p dfsph-web --lib --features threads --target wasm32-unknown-unknown \
  --target-dir "$target/threads" -- \
  -C link-arg=--shared-memory -C link-arg=--max-memory=2147483648 -C link-arg=--import-memory \
  -C link-arg=--export=__wasm_init_tls -C link-arg=--export=__tls_size \
  -C link-arg=--export=__tls_align -C link-arg=--export=__tls_base
"$bindgen" --target web --no-typescript --out-dir "$out/threads" \
  "$target/threads/wasm32-unknown-unknown/web/dfsph_web.wasm"
wasm="$out/threads/dfsph_web_bg.wasm"
echo "build-web: $out/threads (dfsph_web_bg.wasm: $(wc -c <"$wasm") bytes, $(gzip -9c "$wasm" | wc -c) gzipped)" >&2
