"""Executors run one function over many scene indices: in-process, in local processes, or on Ray.

All three call the same function with the same arguments, so results do not depend on the executor; each
index's work is deterministic from (seed, index) alone.

Local workers die with their parent: each asks the kernel for SIGKILL when its parent exits (Linux
``PR_SET_PDEATHSIG``) and also watches its parent's pid, so a ``kill -9`` of ``muble generate`` leaves no worker
writing beside a restarted run. Ray joins an existing cluster only when given its address explicitly
(``dataset.ray_address``); otherwise it starts a private local one, whatever ``RAY_ADDRESS`` says, that only this
machine can reach: every server of it listens on the loopback interface, its token and session files lie in a
folder only this user can enter, and both are gone when the process ends. On a cluster, an index whose node or
worker process is lost runs again on another node (``RAY_TASK_RETRIES``).
"""
from __future__ import annotations

import atexit
import ctypes
import ipaddress
import logging
import multiprocessing
import os
import secrets
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

from muble.core.errors import ConfigError, MubleError, unknown_name

log = logging.getLogger(__name__)

PR_SET_PDEATHSIG = 1  # linux/prctl.h
PARENT_POLL_S = 0.5


def _serial(fn: Callable[[Any], Any], items: list[Any], workers: int, **_: Any) -> Iterator[Any]:
    for item in items:
        yield fn(item)


def die_with_parent(parent_pid: int) -> None:
    """Pool worker initializer: end this process as soon as ``parent_pid`` is gone. Ctrl-C is the parent's to
    handle (it ends the pool and says how to resume): a worker ignores SIGINT instead of printing a traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the watchdog below still works
            pass
    if os.getppid() != parent_pid:  # the parent died before the kernel could be told
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="muble-parent-watchdog", daemon=True).start()


# local workers are renewed every ``workers * TASKS_PER_WORKER`` items (memory a long run of MuJoCo and renderer
# contexts would otherwise accumulate).
TASKS_PER_WORKER = 50


def _pool_ignoring_sigint(context: Any, workers: int) -> Any:
    """A pool whose workers ignore SIGINT from their first instruction: a process started while SIGINT is ignored
    keeps it ignored (Python installs its KeyboardInterrupt handler only over the default), so a Ctrl-C that
    reaches a worker still importing prints no traceback; the parent's own handler is back once they started."""
    if threading.current_thread() is not threading.main_thread():
        return context.Pool(workers, initializer=die_with_parent, initargs=(os.getpid(),))
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        return context.Pool(workers, initializer=die_with_parent, initargs=(os.getpid(),))
    finally:
        signal.signal(signal.SIGINT, previous)


def _processes(fn: Callable[[Any], Any], items: list[Any], workers: int, **_: Any) -> Iterator[Any]:
    """``fn`` over ``items`` in ``workers`` local processes, renewed every ``workers * TASKS_PER_WORKER`` items.

    Workers are renewed by running the items in batches, each in a pool of its own that ends with close and join,
    not with the pool's ``maxtasksperchild``: a pool that replaced workers can hang when it is ended (its
    finalizer waits forever on the task queue's read lock; CPython issue 78178), and a finished 300-episode
    ``muble eval`` did.
    """
    if workers <= 1:
        yield from _serial(fn, items, workers)
        return
    # spawn, not fork: MuJoCo GL contexts and bpy must be created inside each worker.
    context = multiprocessing.get_context("spawn")
    batch = workers * TASKS_PER_WORKER
    for start in range(0, len(items), batch):
        pool = _pool_ignoring_sigint(context, workers)
        finished = False
        try:
            yield from pool.imap_unordered(fn, items[start:start + batch])
            finished = True
        finally:
            if finished:
                pool.close()
                pool.join()
            else:  # an error or the consumer stopped early: the workers are killed
                pool.terminate()


# Ray's environment for a private local cluster. Ray replaces a ``_node_ip_address`` of 127.0.0.1 by the host's
# address and then binds its servers (GCS, raylet, object manager, workers, agents) to every interface; only its
# single-machine mode (the one it uses on macOS and Windows, where it is on by default) keeps the node on the
# loopback address, and with it every server. The token is one of our own in a private file, so Ray neither
# writes ~/.ray/auth_token (at the umask's 0644) nor reads a token left there for another cluster.
_LOOPBACK_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}
_TOKEN_FILE = "auth_token"
RAY_DIR_PREFIX = "muble-ray-"


class _PrivateRay:
    """The private local cluster of this process: started on first use, reused by later calls (one per split
    would each pay Ray's start-up), shut down and its folder removed when the process exits."""

    folder: Path | None = None
    saved_env: dict[str, str | None] = {}
    saved_cluster_flag = True

    @classmethod
    def start(cls, workers: int) -> None:
        import ray
        from ray._private import ray_constants

        # mkdtemp makes the folder 0700; Ray makes its own session folders 0777 inside, which no other user can
        # reach through this one. Under the system's temporary folder, not the dataset root: Ray's Unix socket
        # paths inside it must stay under the kernel's 107 characters.
        cls.folder = Path(tempfile.mkdtemp(prefix=RAY_DIR_PREFIX))
        env = dict(_LOOPBACK_ENV)
        if os.environ.get("RAY_AUTH_MODE", "token").lower() == "token":
            token = cls.folder / _TOKEN_FILE
            fd = os.open(token, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "w") as f:
                f.write(secrets.token_hex(32))
            env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(token))
        cls.saved_env = {k: os.environ.get(k) for k in (*env, "RAY_AUTH_TOKEN")}
        os.environ.pop("RAY_AUTH_TOKEN", None)  # a token in the environment would take precedence over the file
        os.environ.update(env)
        # Ray read this flag when it was imported, perhaps before the environment above was set.
        cls.saved_cluster_flag = ray_constants.ENABLE_RAY_CLUSTER
        ray_constants.ENABLE_RAY_CLUSTER = False
        atexit.register(cls.stop)
        try:
            _refresh_ray_token_state()
            # address="local" always starts a new cluster for this process, never one found in the environment.
            ray.init(address="local", num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     _temp_dir=str(cls.folder / "ray"))
            node_ip = ray.util.get_node_ip_address()
            if not ipaddress.ip_address(node_ip).is_loopback:
                raise ConfigError(f"the private Ray cluster started on {node_ip}, not on the loopback interface "
                                  f"(Ray {ray.__version__} ignores its single-machine mode): use "
                                  "dataset.executor=processes, or start a cluster yourself and pass "
                                  "dataset.ray_address")
        except BaseException:
            cls.stop()
            raise
        log.info("started a private Ray cluster on %s (session files in %s)", node_ip, cls.folder)

    @classmethod
    def stop(cls) -> None:
        import ray
        from ray._private import ray_constants

        if cls.folder is None:
            return
        ray.shutdown()
        ray_constants.ENABLE_RAY_CLUSTER = cls.saved_cluster_flag
        for key, value in cls.saved_env.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        shutil.rmtree(cls.folder, ignore_errors=True)
        cls.folder = None


def _refresh_ray_token_state() -> None:
    """Make Ray re-read the authentication settings and token of the environment (it caches both per process)."""
    try:
        # ray's _raylet.pyi stub lists neither compiled name; a Ray without them raises the ImportError below
        from ray._raylet import AuthenticationTokenLoader, Config  # type: ignore[attr-defined]
    except ImportError:  # a Ray without token authentication: nothing cached
        return
    Config.initialize("")
    AuthenticationTokenLoader.instance().reset_cache()


# An index whose node or worker process is lost (a machine gone, a raylet or worker killed) runs again on another
# node, up to this many times: safe, because an index's work is deterministic from (seed, index) and its files are
# written atomically, so a retry writes the same bytes. Ray's default, named so that it is a decision. An exception
# the function itself raises is not retried (Ray's ``retry_exceptions`` stays off): it would only fail again.
RAY_TASK_RETRIES = 3


def _ray(fn: Callable[[Any], Any], items: list[Any], workers: int, ray_address: str | None = None,
         **_: Any) -> Iterator[Any]:
    import ray

    if not ray.is_initialized():
        if ray_address:
            log.info("joining the Ray cluster at %s (dataset.ray_address)", ray_address)
            ray.init(address=ray_address, log_to_driver=False)
        else:
            if os.environ.get("RAY_ADDRESS"):
                log.warning("RAY_ADDRESS=%s ignored: set dataset.ray_address to use an existing cluster; starting "
                            "a private local one", os.environ["RAY_ADDRESS"])
            _PrivateRay.start(workers)
    remote = ray.remote(num_cpus=1, max_retries=RAY_TASK_RETRIES)(fn)
    pending = [remote.remote(item) for item in items]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        try:
            result = ray.get(done[0])
        except (ray.exceptions.NodeDiedError, ray.exceptions.WorkerCrashedError):
            log.error("a task was lost with its node or worker process %d times (Ray retried it %d times); what "
                      "finished is kept: run the same command again to do the rest", RAY_TASK_RETRIES + 1,
                      RAY_TASK_RETRIES)
            raise
        except ray.exceptions.RayTaskError as e:
            # What the worker raised, as the other executors raise it: a full disk or a refused setting reaches
            # the command line as its own one-line message, not inside Ray's traceback of the remote task.
            cause = getattr(e, "cause", None)
            if isinstance(cause, (OSError, MubleError)):
                raise cause from None
            raise
        yield result


EXECUTORS: dict[str, Callable[..., Iterator[Any]]] = {
    "serial": _serial,
    "processes": _processes,
    "ray": _ray,
}


def run_all(executor: str, fn: Callable[[Any], Any], items: Iterable[Any], workers: int = 1,
            ray_address: str | None = None) -> Iterator[Any]:
    """Results of ``fn`` over ``items`` as they complete (order not guaranteed).

    ``ray_address`` (Ray only): an existing cluster to join; None starts a private local cluster."""
    if executor not in EXECUTORS:
        raise ConfigError(unknown_name("executor", executor, list(EXECUTORS)))
    return EXECUTORS[executor](fn, list(items), workers, ray_address=ray_address)
