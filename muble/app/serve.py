"""``muble serve``: the environment as a server that an agent in another process drives (docs/remote.md).

    muble serve                                   # tcp://127.0.0.1:5555, default config
    muble serve --port 6000 renderer.width=320 renderer.height=240 dataset.root=/data/shopvrb2
    muble serve --host 0.0.0.0                    # other machines may connect: only when asked
    muble serve protocol=shopvrb2_v2 benchmark.split=mini   # the frozen benchmark's shipped episodes, no dataset

Arguments after the options are Hydra overrides of the ``run`` config (robot, renderer, planner, objects …).
The first line printed is ``muble serve: listening on <endpoint>``. Every option value is checked before
anything is built: a bad one exits with code 2 and one paragraph saying what is valid.
"""
from __future__ import annotations

import argparse
import functools
import ipaddress
import logging
import math
import signal
import socket
from typing import Any, Callable

from muble.remote.wire import DEFAULT_HOST, DEFAULT_PORT, HARD_LIMIT_BYTES, MAX_REQUEST_BYTES, PROTOCOL

log = logging.getLogger(__name__)

MAX_SESSIONS_LIMIT = 64  # episodes open at once: each holds a MuJoCo world (and a renderer) in memory
MAX_OBJECTS_LIMIT = 1000  # the scene files' own bound (muble.io.scene_io.MAX_OBJECTS)
MIN_REQUEST_BYTES = 1024  # a reset of a generated scene fits; less would refuse every request
LOG_FORMAT = "%(asctime)s %(name)s %(levelname)s: %(message)s"


def _integer(low: int, high: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer in {low}..{high}, got {text[:40]!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be an integer in {low}..{high}, got {value}")
        return value

    return parse


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of seconds above 0, got {text[:40]!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds above 0, got {text[:40]}")
    return value


def _host(text: str) -> str:
    """An address ZeroMQ can bind: an IP address, ``localhost``, ``*`` or a network interface's name."""
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        pass
    interfaces = [name for _, name in socket.if_nameindex()]
    if text in ("localhost", "*") or text in interfaces:
        return text
    raise argparse.ArgumentTypeError(
        f"{text[:60]!r} is neither an IP address nor an interface of this machine; use 127.0.0.1 (this machine "
        f"only, the default), 0.0.0.0 (every interface), one of this machine's addresses or an interface name "
        f"({', '.join(interfaces) or 'none found'})")


class _Parser(argparse.ArgumentParser):
    """argparse with its errors in one line: what is wrong and where the options are listed."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (`{self.prog} --help` lists the options)\n")


def parser() -> argparse.ArgumentParser:
    from muble.remote.server import (DEFAULT_MAX_OBJECTS, DEFAULT_MAX_SESSIONS, DEFAULT_SESSION_TIMEOUT,
                                     DEFAULT_STEP_TIMEOUT)

    p = _Parser(prog="muble serve", description=f"serve episodes over {PROTOCOL} (ZeroMQ)")
    p.add_argument("--host", type=_host, default=DEFAULT_HOST,
                   help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=_integer(0, 65535), default=DEFAULT_PORT, help="TCP port; 0 picks a free one")
    p.add_argument("--max-sessions", type=_integer(1, MAX_SESSIONS_LIMIT), default=DEFAULT_MAX_SESSIONS,
                   help=f"episodes open at once (default {DEFAULT_MAX_SESSIONS})")
    p.add_argument("--session-timeout", type=_seconds, default=DEFAULT_SESSION_TIMEOUT,
                   help=f"seconds without a request before a session closes (default {DEFAULT_SESSION_TIMEOUT:g})")
    p.add_argument("--max-request-bytes", type=_integer(MIN_REQUEST_BYTES, HARD_LIMIT_BYTES),
                   default=MAX_REQUEST_BYTES, help=f"largest request accepted (default {MAX_REQUEST_BYTES})")
    p.add_argument("--max-objects", type=_integer(1, MAX_OBJECTS_LIMIT), default=DEFAULT_MAX_OBJECTS,
                   help=f"objects per scene (default {DEFAULT_MAX_OBJECTS})")
    p.add_argument("--step-timeout", type=_seconds, default=DEFAULT_STEP_TIMEOUT,
                   help=f"seconds a reset or act may take before its episode is abandoned "
                   f"(default {DEFAULT_STEP_TIMEOUT:g})")
    p.add_argument("--no-render", action="store_true", help="no images (no renderer, faster)")
    p.add_argument("--idle-exit", type=_seconds, default=None, help="stop after this many seconds without a request")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of the run config (key=value)")
    return p


def episode_factory(overrides: tuple[str, ...], render: bool, verbose: bool) -> Any:
    """The ``EpisodeFactory`` of ``muble serve``'s config, built inside the simulation process (a fresh
    interpreter: the command line's quiet logging is set up here again)."""
    from muble.app.config import compose
    from muble.dataset.production import with_split
    from muble.episode.sources import EpisodeFactory
    from muble.quiet import quiet_third_party

    quiet_third_party(verbose)
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO, format=LOG_FORMAT)
    return EpisodeFactory(with_split(compose("run", list(overrides))), render=render)


def main(argv: list[str]) -> int:
    from muble.app.config import compose
    from muble.app.usage import USAGE_EXIT_CODE, explain_config_error, report
    from muble.remote.server import EpisodeServer

    args = parser().parse_args(argv)
    try:
        cfg = compose("run", args.overrides)
    except Exception as e:  # noqa: BLE001 - a config error is a usage error; anything else is re-raised
        message = explain_config_error(e)
        if message is None:
            raise
        report("muble serve", message)
        return USAGE_EXIT_CODE
    from muble.app.plan import resolve

    plan = resolve(cfg, files="serve")  # protocol=NAME: its split's stored episodes, from dataset.root or shipped
    cfg, split = plan.config, plan.split
    verbose = logging.getLogger().isEnabledFor(logging.DEBUG)
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT)
    if split is not None:
        log.info("protocol %s: serving the stored episodes of split %s (reset with episode {split: %s, index: i})",
                 cfg.benchmark.protocol, split, split)
    build = functools.partial(episode_factory, tuple(args.overrides), not args.no_render, verbose)
    server = EpisodeServer(cfg, build, render=not args.no_render, host=args.host, port=args.port,
                           max_sessions=args.max_sessions, session_timeout=args.session_timeout,
                           max_request_bytes=args.max_request_bytes, max_objects=args.max_objects,
                           step_timeout=args.step_timeout)
    print(f"muble serve: listening on {server.endpoint}", flush=True)
    signal.signal(signal.SIGTERM, _stop)  # `kill` stops as Ctrl-C does: episodes closed, nothing left behind
    try:
        server.serve(idle_exit=args.idle_exit)
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    return 0


def _stop(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt
