"""The oracle through ``gymnasium.make("MuBlE/ShopVRB2-v0")`` and through ``muble serve``: ten templates each.

One episode per template, the first generated scene (seed 0) that yields it, as in
``tests/tasks/test_tasks_oracle_physics.py``. The in-process run (the Gymnasium environment: ``run_episode`` in
this process) must succeed on all ten; the remote run (``muble serve`` in a subprocess, the oracle deciding in
this process over the protocol) must end every episode with the same outcome and the same primitives.
"""
from __future__ import annotations

import numpy as np
import pytest

from muble import get_registry
from muble.app.config import SHOPVRB2_TEMPLATES

from tests.remote.server import ServerProcess

pytestmark = pytest.mark.slow

SEED = 0
MAX_SCENES = 40


@pytest.fixture(scope="module")
def episodes():
    """template -> the first scene index (seed 0) with an instruction of it."""
    from muble.app.config import compose
    from muble.episode.components import build_components, scene_generator

    cfg = compose("run", [f"seed={SEED}"])
    generator = scene_generator(cfg, build_components(cfg, renderer=False, task=False)["object_set"])
    registry, found, scenes = get_registry(), {}, {}
    try:
        for template in SHOPVRB2_TEMPLATES:
            task = registry.create("task", template, {})
            for index in range(MAX_SCENES):
                if index not in scenes:
                    scenes[index] = generator.generate(index)
                if task.generate(scenes[index], np.random.default_rng([SEED, index, 1])):
                    found[template] = index
                    break
    finally:
        generator.close()
    assert set(found) == set(SHOPVRB2_TEMPLATES), found
    return found


@pytest.fixture(scope="module")
def in_process(episodes):
    import gymnasium

    import muble.gym  # noqa: F401
    from muble.gym.policy import AgentPolicy

    env = gymnasium.make("MuBlE/ShopVRB2-v0", render=False, overrides=[f"seed={SEED}"])
    policy = AgentPolicy(get_registry().create("agent", "oracle", {}))
    records = {}
    try:
        for template, index in episodes.items():
            obs, info = env.reset(options={"scene_index": index, "template": template})
            policy.reset(obs, info)
            reward, done = 0.0, False
            while not done:
                obs, reward, terminated, truncated, step_info = env.step(policy(obs))
                done = terminated or truncated
            records[template] = {"outcome": step_info["outcome"], "reward": reward, "error": step_info.get("error"),
                                 "primitives": step_info["actions"]}
    finally:
        env.close()
    return records


@pytest.fixture(scope="module")
def remote(episodes):
    from muble.remote import RemoteClient, run_agent

    server = ServerProcess("--no-render", f"seed={SEED}", idle_exit=300)
    oracle = get_registry().create("agent", "oracle", {})
    records = {}
    try:
        with RemoteClient(server.endpoint, timeout=600) as client:
            for template, index in episodes.items():
                records[template] = run_agent(oracle, client, {"scene_index": index, "template": template})
    finally:
        server.stop()
    return records


def test_oracle_actions_through_gymnasium_succeed_on_every_template(in_process):
    failed = {t: r for t, r in in_process.items() if r["outcome"] != "success" or r["reward"] != 1.0}
    assert not failed, failed


def test_remote_oracle_gets_the_in_process_outcomes(in_process, remote):
    for template in SHOPVRB2_TEMPLATES:
        here, there = in_process[template], remote[template]
        assert there["outcome"] == here["outcome"], (template, here, there)
        assert there["primitives"] == here["primitives"], template
