"""An agent author's first hour (issue 56): the mistakes people make end in one paragraph that names the fix (exit
2, no traceback), and the frozen benchmark's shipped episodes play everywhere with no dataset: ``muble eval``,
Gymnasium and ``muble serve``."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from muble import get_registry
from muble.core.errors import ConfigError
from tests.app.usage_probe import run_many

REPO = Path(__file__).resolve().parents[2]


def _one_paragraph(result: dict, *words: str) -> None:
    assert result["code"] == 2, result
    stderr = result["stderr"].strip()
    assert "Traceback" not in stderr and len(stderr.splitlines()) == 1 and stderr.startswith("muble "), stderr
    for word in words:
        assert word in stderr, (word, stderr)


def test_every_mistake_names_its_fix(tmp_path):
    where = [f"hydra.run.dir={tmp_path / 'run'}"]
    cases = {
        ("eval", "protocol=shopvrb2_v2", "benchmark.split=minii", "agent=oracle", *where):
            ["unknown split 'minii' of protocol 'shopvrb2_v2' (did you mean 'mini'?); valid split names:"],
        ("eval", "protocol=shopvrb2_v2", "benchmark.split=Physical", "agent=oracle", *where):
            ["(names are case-sensitive: did you mean 'physical'?)"],
        ("eval", "protocol=shopvrb2_v2", "benchmark.split=val", "agent=oracle", *where):
            ["unknown split 'val'", "closed_loop", "physical", "benchmark.split=", "dataset.root=DIR and no protocol="],
        ("eval", "agent=oracle", *where): ["does not exist", "protocol=shopvrb2_v2"],
        ("serve", "protocol=shopvrb2_v2", "benchmark.split=Mini"): ["did you mean 'mini'"],
        ("serve", "protocol=shopvrb2_v2", "benchmark.split=train"): ["does not ship", "muble generate"],
        ("serve", "protocol=shopvrb2_v2", "benchmark.split=closed_loop"):
            ["sets disturbances", "muble eval protocol=shopvrb2_v2 benchmark.split=closed_loop"],
        ("task=measure_com_single", *where): ["generator.physical_properties=[friction,com_offset,contents]",
                                              "docs/physical_properties.md"],
    }
    for result, words in zip(run_many([list(argv) for argv in cases], tmp_path), cases.values()):
        _one_paragraph(result, *words)
    assert not (tmp_path / "run").exists()


def test_the_remote_example_names_the_valid_agents_for_a_mistyped_one():
    done = subprocess.run([sys.executable, "docs/examples/remote_agent.py", "--agent", "heuristc"], cwd=REPO,
                          capture_output=True, text=True, timeout=120, env={**os.environ, "MUJOCO_GL": "egl"})
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert "unknown agent 'heuristc'" in done.stderr and "oracle" in done.stderr


def test_a_server_without_data_says_how_to_serve_stored_episodes():
    from muble.remote.episodes import EpisodeRequest
    from muble.remote.wire import ProtocolError

    with pytest.raises(ProtocolError) as info:
        EpisodeRequest.check({"split": "mini", "index": 0}, list(get_registry().names("task")), None, 10)
    message = str(info.value)
    assert "muble serve protocol=shopvrb2_v2" in message and "muble data" in message


@pytest.fixture()
def cache(tmp_path, monkeypatch) -> Path:
    monkeypatch.setenv("MUBLE_DATA_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _play(env, options: dict) -> dict:
    from muble.gym.policy import AgentPolicy

    policy = AgentPolicy(get_registry().create("agent", "oracle", {}))
    obs, info = env.reset(options=options)
    policy.reset(obs, info)
    done = False
    while not done:
        obs, reward, terminated, truncated, step = env.step(policy(obs))
        done = terminated or truncated
    return {**step, "source": info["source"], "reward": reward}


@pytest.mark.slow
def test_gymnasium_plays_a_shipped_episode_with_no_dataset_root(cache):
    import gymnasium

    import muble.gym  # noqa: F401

    env = gymnasium.make("MuBlE/ShopVRB2-v0", render=False)
    try:
        with pytest.raises(ConfigError, match=r"set dataset.root=DIR .*or protocol=NAME"):
            env.reset(options={"split": "mini", "index": 0})
    finally:
        env.close()
    # A fresh environment after a refused reset: Gymnasium's passive checker keeps the failed reset's state.
    env = gymnasium.make("MuBlE/ShopVRB2-v0", render=False, overrides=["protocol=shopvrb2_v2"])
    try:
        with pytest.raises(ConfigError, match="sets disturbances that act while its episodes run"):
            env.reset(options={"split": "closed_loop", "index": 0})
    finally:
        env.close()
    env = gymnasium.make("MuBlE/ShopVRB2-v0", render=False, overrides=["protocol=shopvrb2_v2"])
    try:
        played = _play(env, {"split": "mini", "index": 0})
    finally:
        env.close()
    assert played["outcome"] == "success" and played["reward"] == 1.0, played
    assert played["source"] == {"kind": "dataset", "split": "mini", "index": 0}
    assert (cache / "shopvrb2_v2").is_dir()  # the shipped files, unpacked once


@pytest.mark.slow
def test_muble_serve_plays_a_shipped_episode_with_no_dataset_root(cache):
    from muble.remote import RemoteClient, RemoteError, run_agent
    from tests.remote.server import ServerProcess

    server = ServerProcess("--no-render", "protocol=shopvrb2_v2", "benchmark.split=mini", idle_exit=120)
    try:
        with RemoteClient(server.endpoint, timeout=300) as client:
            assert client.hello()["stored_episodes"] is True
            record = run_agent(get_registry().create("agent", "oracle", {}), client, {"split": "mini", "index": 0})
            with pytest.raises(RemoteError, match="no split 'physical'; its splits: mini"):
                client.reset({"split": "physical", "index": 0})
    finally:
        server.stop()
    assert record["outcome"] == "success", record


@pytest.mark.slow
def test_a_limited_eval_is_quiet_and_labelled_first_n(tmp_path):
    import json

    from tests.app.test_app_protocol import muble

    out = tmp_path / "run"
    done = muble("eval", "protocol=shopvrb2_v2", "agent=oracle", "evaluation.limit=1", "dataset.workers=1",
                 f"hydra.run.dir={out}", cwd=tmp_path, env={"MUBLE_DATA_CACHE": str(tmp_path / "cache")})
    assert done.returncode == 0, done.stderr[-3000:]
    printed = done.stdout + done.stderr
    assert "step " not in printed and "muble.episode.runner" not in printed, printed  # no line per primitive
    assert "split mini, first 1 of 100 episodes (evaluation.limit)" in done.stdout
    results = json.loads((out / "results.json").read_text())
    assert results["splits"]["mini"]["partial"] == {"first": 1, "of": 100}
    assert "first 1 of 100 episodes" in (out / "summary.md").read_text()
    record = json.loads((out / "episodes_mini.jsonl").read_text().splitlines()[0])
    assert record["outcome"] == "success" and record["traceback"] is None


@pytest.mark.slow
def test_a_hung_agent_ends_its_episode_as_timeout_in_muble_eval_and_the_next_runs(cache, tmp_path, monkeypatch):
    import time

    from omegaconf import OmegaConf

    import muble.evaluation.episodes as episodes
    from muble.app.config import compose
    from muble.dataset.protocol import load_protocol, shipped_root
    from tests.episode.test_episode_decision_timeout import Hanging

    root = shipped_root(load_protocol("shopvrb2_v2"), "mini")
    cfg = compose("eval", ["protocol=shopvrb2_v2", f"dataset.root={root}", f"output.dir={tmp_path}",
                           "evaluation.decision_timeout=2", "dataset.splits=[mini]"])
    config = OmegaConf.to_container(cfg, resolve=True)
    agent, built = Hanging(), episodes.build_components
    monkeypatch.setattr(episodes, "build_components", lambda c: {**built(c), "agent": agent})
    began = time.monotonic()
    hung = episodes.evaluate_index(episodes.EvalJob(config, "mini", 0))
    took = time.monotonic() - began
    assert hung["outcome"] == "timeout" and "agent.act took longer than 2 s" in hung["error"], hung
    assert took < 2 + 5 + 10, took  # the limit, the acceptance's 5 s, and building and settling the scene
    agent.hang = False
    assert episodes.evaluate_index(episodes.EvalJob(config, "mini", 1))["outcome"] == "success"
