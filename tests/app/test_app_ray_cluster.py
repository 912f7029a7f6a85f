"""`dataset.executor=ray` on a real cluster of two nodes, a head and a worker each started with `ray start` on this
machine, with the worker node killed while it runs an index: `muble generate` and `muble eval` still finish, and
what they write equals a single-process run's (Ray runs the lost index again; each index is deterministic from
(seed, index) and its files are written atomically, so the retry writes the same bytes).

Every node runs on 127.0.0.1 in a session of its own, so killing a node is killing its session (the raylet, its
agents and the workers it started) and cleaning up kills every session the test started, by process id. Not
`ray stop --force`: that ends every Ray process of this user on the machine, other people's clusters included.
"""
from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from muble.io.atomic import TMP_PREFIX

pytest.importorskip("ray")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds node processes in /proc")]

REPO = Path(__file__).parents[2]
# The whole test, cluster start-up and both reference runs included, ends within this; every subprocess gets what
# is left of it.
TEST_BUDGET_S = 480
RAY_START_S = 120  # one `ray start`; it takes 5-10 s on an idle machine
GONE_S = 30  # how long killed processes may take to disappear from /proc
OBJECT_STORE_BYTES = 100 * 1024 * 1024  # Ray's minimum is 75 MiB; results here are a few KiB
SCENES = 6
EPISODES = 4
GENERATE = ["dataset.splits=[val]", f"dataset.sizes=[{SCENES}]", "dataset.sequences=false",
            "dataset.templates=[measure_weight_single,move_single,stack_simple]", "renderer.width=212",
            "renderer.height=120"]
EVALUATE = ["agent=oracle", "dataset.splits=[val]", f"evaluation.limit={EPISODES}"]
# What differs between two runs of one episode by design: wall times, and the machine's description.
RUN_DEPENDENT = ("timing", "platform")

# `ray start` for a worker node, with everything else kept in Ray's single-machine mode (the environment's
# RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0). On Linux Ray replaces a node address of 127.0.0.1 by the host's network
# address and binds its servers to every interface; in single-machine mode the node stays on 127.0.0.1 and so does
# every server, but the CLI then refuses to add a worker node. This lifts that refusal only, in the CLI's own view
# of the flag.
WORKER_NODE_START = """
import sys, types
import ray._private.ray_constants as constants
import ray.scripts.scripts as cli

view = types.ModuleType(constants.__name__)
view.__dict__.update(vars(constants))
view.ENABLE_RAY_CLUSTER = True
cli.ray_constants = view
sys.exit(cli.main())
"""


class Deadline:
    def __init__(self, seconds: float):
        self.end = time.monotonic() + seconds

    def left(self, cap: float = float("inf")) -> float:
        left = self.end - time.monotonic()
        if left <= 0:
            pytest.fail(f"the test ran past its {TEST_BUDGET_S} s budget")
        return min(left, cap)


def session_of(pid: int | str) -> int | None:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return None if fields[0] == "Z" else int(fields[3])  # state, ppid, pgrp, session


def command_line(pid: int | str) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ").strip()
    except OSError:
        return ""


def processes_of(sessions: set[int]) -> list[int]:
    return [int(p) for p in os.listdir("/proc") if p.isdigit() and session_of(p) in sessions]


@dataclass
class Node:
    name: str
    session: int  # the pid of its `ray start`, which leads the session every process of the node is in
    killed: bool = False


@dataclass
class LocalRayCluster:
    """Ray nodes on this machine, each started by `ray start` in a session of its own."""

    folder: Path
    deadline: Deadline
    env: dict[str, str] = field(default_factory=dict)
    nodes: list[Node] = field(default_factory=list)
    address: str = ""

    def __post_init__(self) -> None:
        token = self.folder / "auth_token"
        token.write_text(secrets.token_hex(32))
        token.chmod(0o600)
        (self.folder / "home").mkdir()
        (self.folder / "worker_node_start.py").write_text(WORKER_NODE_START)
        self.env = {**os.environ, "HOME": str(self.folder / "home"), "RAY_AUTH_MODE": "token",
                    "RAY_AUTH_TOKEN_PATH": str(token), "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",
                    "RAY_USAGE_STATS_ENABLED": "0",
                    # Ray's default niceness of 15 starves its workers on a machine shared with other jobs.
                    "RAY_worker_niceness": "0", "LP_NUM_THREADS": "1",
                    "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "HYDRA_FULL_ERROR": "0"}
        for key in ("RAY_ADDRESS", "RAY_AUTH_TOKEN"):
            self.env.pop(key, None)

    def _start(self, name: str, command: list[str]) -> Node:
        log = self.folder / f"{name}.log"
        with log.open("w") as out:
            starter = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=self.env, cwd=REPO,
                                       start_new_session=True)
        node = Node(name, starter.pid)
        self.nodes.append(node)  # before waiting: a start that hangs is still cleaned up
        try:
            starter.wait(timeout=self.deadline.left(RAY_START_S))
        except subprocess.TimeoutExpired:
            pytest.fail(f"`ray start` of {name} did not return: {log.read_text()[-2000:]}")
        assert starter.returncode == 0, log.read_text()[-3000:]
        return node

    def start_head(self) -> Node:
        with socket.socket() as s:  # a free port for the GCS
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        self.address = f"127.0.0.1:{port}"
        return self._start("head", [str(Path(sys.executable).parent / "ray"), "start", "--head",
                                    "--node-ip-address=127.0.0.1", f"--port={port}", *self._node_options("head"),
                                    "--include-dashboard=false"])

    def add_worker_node(self) -> Node:
        name = f"worker{len(self.nodes)}"
        return self._start(name, [sys.executable, str(self.folder / "worker_node_start.py"), "start",
                                  f"--address={self.address}", "--node-ip-address=127.0.0.1",
                                  *self._node_options(name)])

    def _node_options(self, name: str) -> list[str]:
        # A folder of its own per node, under a short path: Ray's Unix sockets live there (107-character limit).
        return ["--num-cpus=1", f"--object-store-memory={OBJECT_STORE_BYTES}", f"--temp-dir={self.folder / name}",
                "--disable-usage-stats"]

    def running(self, node: Node, function: str) -> list[int]:
        """The node's worker processes running ``function`` now (Ray titles them ``ray::FUNCTION``)."""
        return [pid for pid in processes_of({node.session}) if command_line(pid).startswith(f"ray::{function}")]

    def kill(self, node: Node) -> None:
        """What a crashed machine does to its node: every process of it ends at once, with no goodbye."""
        _kill_and_wait({node.session})
        node.killed = True

    def close(self) -> None:
        _kill_and_wait({node.session for node in self.nodes})


def _kill_and_wait(sessions: set[int]) -> None:
    gone_by = time.monotonic() + GONE_S
    while time.monotonic() < gone_by:
        left = processes_of(sessions)
        if not left:
            return
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(0.2)
    assert not processes_of(sessions), f"Ray processes outlived SIGKILL: {processes_of(sessions)}"


def muble_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "muble.app.cli", *args]


def run_killing_node(cluster: LocalRayCluster, command: list[str], node: Node, function: str,
                     log: Path) -> tuple[int, str]:
    """Run ``command`` and kill ``node`` as soon as one of its workers runs ``function``; the command's exit
    status and output. The node must have been killed busy: otherwise nothing was lost and nothing is shown."""
    with log.open("w") as out:
        proc = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=cluster.env, cwd=REPO,
                                start_new_session=True)
    try:
        while proc.poll() is None:
            if time.monotonic() >= cluster.deadline.end:
                pytest.fail(f"{command[3]} did not finish within the test's budget: {log.read_text()[-3000:]}")
            if not node.killed and cluster.running(node, function):
                cluster.kill(node)
            time.sleep(0.1)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert node.killed, f"{node.name} never ran {function}, so it was not killed busy: {log.read_text()[-3000:]}"
    return proc.returncode, log.read_text()


def tree(root: Path) -> dict[str, bytes]:
    """Every file of a dataset, by path; a temporary that a killed worker left half-written is not part of it
    (its manifest leaves such files out, and the next run removes them)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and not p.name.startswith(TMP_PREFIX)}


def episodes(out: Path) -> list[dict]:
    records = [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines()]
    return [{k: v for k, v in r.items() if k not in RUN_DEPENDENT} for r in records]


def run_serial(args: list[str], deadline: Deadline, env: dict[str, str]) -> None:
    done = subprocess.run(muble_cmd(*args, "dataset.executor=serial"), capture_output=True, text=True, env=env,
                          cwd=REPO, timeout=deadline.left())
    assert done.returncode == 0, done.stderr[-3000:]


def test_generate_and_eval_survive_a_lost_node_and_match_one_process(tmp_path):
    deadline = Deadline(TEST_BUDGET_S)
    # Short: Ray's Unix socket paths lie under it.
    folder = Path(tempfile.mkdtemp(prefix="mrc-", dir="/tmp"))
    cluster = LocalRayCluster(folder, deadline)
    try:
        cluster.start_head()
        # The reference runs, in one process (the cluster's head starts meanwhile, it waits idle).
        reference, reference_eval = tmp_path / "serial", tmp_path / "serial-eval"
        run_serial(["generate", *GENERATE, f"dataset.root={reference}", f"hydra.run.dir={tmp_path / 'run0'}"],
                   deadline, cluster.env)
        run_serial(["eval", *EVALUATE, f"dataset.root={reference}", f"output.dir={reference_eval}",
                    f"hydra.run.dir={tmp_path / 'run1'}"], deadline, cluster.env)

        on_ray = ["dataset.executor=ray", f"dataset.ray_address={cluster.address}"]
        root = tmp_path / "ray"
        rc, output = run_killing_node(
            cluster, muble_cmd("generate", *GENERATE, *on_ray, f"dataset.root={root}",
                               f"hydra.run.dir={tmp_path / 'run2'}"),
            cluster.add_worker_node(), "produce_index", tmp_path / "generate.log")
        assert rc == 0, output[-3000:]
        assert "will be retried" in output, output[-3000:]  # what the user is shown (docs/scene_generation.md)
        assert tree(root) == tree(reference)

        out = tmp_path / "ray-eval"
        rc, output = run_killing_node(
            cluster, muble_cmd("eval", *EVALUATE, *on_ray, f"dataset.root={reference}", f"output.dir={out}",
                               f"hydra.run.dir={tmp_path / 'run3'}"),
            cluster.add_worker_node(), "evaluate_index", tmp_path / "eval.log")
        assert rc == 0, output[-3000:]
        assert "will be retried" in output, output[-3000:]
        assert episodes(out) == episodes(reference_eval)
        assert len(episodes(out)) == EPISODES
    finally:
        cluster.close()
        shutil.rmtree(folder, ignore_errors=True)
