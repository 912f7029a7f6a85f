"""Executors run one function over many scene indices: in-process, in local processes, or on Ray.

All three call the same function with the same arguments, so results do not depend on the executor; each
index's work is deterministic from (seed, index) alone.
"""
from __future__ import annotations

import logging
import multiprocessing
from typing import Any, Callable, Iterable, Iterator

from muble.core.errors import ConfigError, unknown_name

log = logging.getLogger(__name__)


def _serial(fn: Callable[[Any], Any], items: list[Any], workers: int) -> Iterator[Any]:
    for item in items:
        yield fn(item)


def _processes(fn: Callable[[Any], Any], items: list[Any], workers: int) -> Iterator[Any]:
    if workers <= 1:
        yield from _serial(fn, items, workers)
        return
    # spawn, not fork: MuJoCo GL contexts and bpy must be created inside each worker.
    with multiprocessing.get_context("spawn").Pool(workers, maxtasksperchild=50) as pool:
        yield from pool.imap_unordered(fn, items)


def _ray(fn: Callable[[Any], Any], items: list[Any], workers: int) -> Iterator[Any]:
    import ray

    if not ray.is_initialized():
        # Connects to a running cluster when RAY_ADDRESS is set, else starts a local one.
        ray.init(num_cpus=workers or None, include_dashboard=False, log_to_driver=False)
    remote = ray.remote(num_cpus=1)(fn)
    pending = [remote.remote(item) for item in items]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        yield ray.get(done[0])


EXECUTORS: dict[str, Callable[[Callable[[Any], Any], list[Any], int], Iterator[Any]]] = {
    "serial": _serial,
    "processes": _processes,
    "ray": _ray,
}


def run_all(executor: str, fn: Callable[[Any], Any], items: Iterable[Any], workers: int = 1) -> Iterator[Any]:
    """Results of ``fn`` over ``items`` as they complete (order not guaranteed)."""
    if executor not in EXECUTORS:
        raise ConfigError(unknown_name("executor", executor, list(EXECUTORS)))
    return EXECUTORS[executor](fn, list(items), workers)
