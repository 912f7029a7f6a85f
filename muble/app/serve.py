"""``muble serve``: the environment as a server that an agent in another process drives (docs/remote.md).

    muble serve                                   # tcp://127.0.0.1:5555, default config
    muble serve --port 6000 renderer.width=320 renderer.height=240 dataset.root=/data/shopvrb2
    muble serve --host 0.0.0.0                    # other machines may connect: only when asked

Arguments after the options are Hydra overrides of the ``run`` config (robot, renderer, planner, objects …).
The first line printed is ``muble serve: listening on <endpoint>``.
"""
from __future__ import annotations

import argparse
import logging
import sys

from muble.remote.protocol import DEFAULT_HOST, DEFAULT_PORT, MAX_REQUEST_BYTES, PROTOCOL

log = logging.getLogger(__name__)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="muble serve", description=f"serve episodes over {PROTOCOL} (ZeroMQ)")
    p.add_argument("--host", default=DEFAULT_HOST, help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help="TCP port; 0 picks a free one")
    p.add_argument("--max-sessions", type=int, default=2, help="episodes open at once")
    p.add_argument("--session-timeout", type=float, default=900.0, help="seconds before an idle session closes")
    p.add_argument("--max-request-bytes", type=int, default=MAX_REQUEST_BYTES)
    p.add_argument("--no-render", action="store_true", help="no images (no renderer, faster)")
    p.add_argument("--idle-exit", type=float, default=None, help="stop after this many seconds without a request")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of the run config (key=value)")
    return p


def main(argv: list[str]) -> int:
    from muble.app.config import compose
    from muble.episode.sources import EpisodeFactory
    from muble.remote.server import EpisodeServer

    args = parser().parse_args(argv)
    if not 0 <= args.port < 65536:
        print(f"muble serve: error: --port must be in 0..65535, got {args.port}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    factory = EpisodeFactory(compose("run", args.overrides), render=not args.no_render)
    server = EpisodeServer(factory, args.host, args.port, max_sessions=args.max_sessions,
                           session_timeout=args.session_timeout, max_request_bytes=args.max_request_bytes)
    print(f"muble serve: listening on {server.endpoint}", flush=True)
    try:
        server.serve(idle_exit=args.idle_exit)
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    return 0
