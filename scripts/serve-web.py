#!/usr/bin/env python3
"""Serve the web site that scripts/build-web.sh built, with the headers WebAssembly threads need.

    scripts/serve-web.py OUTDIR [PORT]        (PORT: 8080 by default)

then open http://127.0.0.1:PORT/ . Every response carries

    Cross-Origin-Opener-Policy: same-origin
    Cross-Origin-Embedder-Policy: require-corp

which make the page cross-origin isolated (`self.crossOriginIsolated`): SharedArrayBuffer is
available, and index.html loads the threaded build (OUTDIR/threads/, the solver on a pool of
Web Workers). Served without them (`--no-isolation`, or any plain static server) the page
runs the single-threaded build. Binds 127.0.0.1 only; python3's standard library only.
"""

import functools
import http.server
import os
import sys


class Handler(http.server.SimpleHTTPRequestHandler):
    isolate = True

    def end_headers(self):
        if self.isolate:
            self.send_header("Cross-Origin-Opener-Policy", "same-origin")
            self.send_header("Cross-Origin-Embedder-Policy", "require-corp")
        # A rebuilt site is picked up on reload.
        self.send_header("Cache-Control", "no-cache")
        super().end_headers()


def main(argv):
    args = [a for a in argv[1:] if not a.startswith("--")]
    flags = [a for a in argv[1:] if a.startswith("--")]
    if not 1 <= len(args) <= 2 or any(f != "--no-isolation" for f in flags):
        sys.exit(f"usage: {argv[0]} OUTDIR [PORT] [--no-isolation]")
    directory = args[0]
    if not os.path.isfile(os.path.join(directory, "index.html")):
        sys.exit(f"error: {directory} holds no site (no index.html); build one with "
                 f"scripts/build-web.sh {directory}")
    port = int(args[1]) if len(args) == 2 else 8080
    Handler.isolate = "--no-isolation" not in flags
    threaded = os.path.isfile(os.path.join(directory, "threads", "dfsph_web_bg.wasm"))
    Handler.extensions_map = {**Handler.extensions_map, ".wasm": "application/wasm",
                              ".js": "text/javascript"}
    handler = functools.partial(Handler, directory=directory)
    with http.server.ThreadingHTTPServer(("127.0.0.1", port), handler) as server:
        if not Handler.isolate:
            mode = "no isolation (single-threaded)"
        elif threaded:
            mode = "cross-origin isolated (threads)"
        else:
            # index.html falls back to the single-threaded build when threads/ is missing.
            mode = ("cross-origin isolated, but the site has no threaded build (threads/), so "
                    "the page runs single-threaded; scripts/build-web.sh builds it with a "
                    "nightly toolchain and its rust-src component")
        print(f"serving {directory} at http://127.0.0.1:{port}/ — {mode}", flush=True)
        try:
            server.serve_forever()
        except KeyboardInterrupt:
            pass


if __name__ == "__main__":
    main(sys.argv)
