"""A time limit per decision (``run_episode(decision_timeout=…)``, ``evaluation.decision_timeout``) and an agent's
traceback: a hung agent ends its episode as ``timeout`` and the next episode runs; one that raises leaves its
traceback in the log and in the result. Symbolic episodes; ``tests/app/test_app_first_hour.py`` runs one in
``muble eval``, with physics."""
from __future__ import annotations

import logging
import threading
import time

import pytest

from muble import Agent, Outcome
from muble.episode import run_episode
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.success import check
from muble_plugins.common.symbolic import SymbolicWorld

from tests.episode.test_episode_integrity import instruction_for

LIMIT_S = 1.0
SLACK_S = 5.0  # the acceptance bound: the episode ends within the limit plus this


@pytest.fixture(scope="module")
def episode():
    return instruction_for("move_single")


class Hanging(Agent):
    """The oracle, but its first decision of an episode hangs while ``hang`` is set: asleep in a C call, or
    spinning in a Python loop."""

    def __init__(self, how: str = "sleep"):
        self.inner, self.how, self.hang, self.threads = OracleAgent(), how, True, set()

    def reset(self, instruction, observation, **kwargs):
        self.inner.reset(instruction, observation, **kwargs)
        self.first = True

    def act(self, instruction, observation):
        self.threads.add(threading.current_thread().name)
        if self.hang and self.first:
            self.first, self.hung = False, threading.current_thread()
            if self.how == "sleep":
                time.sleep(60)
            else:
                while True:
                    pass
        return self.inner.act(instruction, observation)


@pytest.mark.parametrize("how", ["sleep", "spin"])
def test_a_hung_decision_ends_its_episode_as_timeout_and_the_next_episode_runs(episode, how):
    task, ins, scene = episode
    agent = Hanging(how)
    start = time.monotonic()
    result = run_episode(ins, SymbolicWorld(scene), agent, check, decision_timeout=LIMIT_S)
    took = time.monotonic() - start
    assert result.outcome is Outcome.TIMEOUT, (result.outcome, result.error)
    assert "agent.act took longer than 1 s" in result.error and "evaluation.decision_timeout" in result.error
    assert took < LIMIT_S + SLACK_S
    agent.hang = False
    again = run_episode(ins, SymbolicWorld(scene), agent, check, decision_timeout=LIMIT_S)
    assert again.outcome is Outcome.SUCCESS, (again.outcome, again.error)
    assert agent.threads == {"muble-agent"}  # every call of an episode on its worker thread
    if how == "spin":  # a Python loop is interrupted: the abandoned thread ends
        agent.hung.join(timeout=SLACK_S)
        assert not agent.hung.is_alive()


def test_without_a_limit_the_agent_runs_on_the_callers_thread(episode):
    task, ins, scene = episode
    agent = Hanging()
    agent.hang = False
    result = run_episode(ins, SymbolicWorld(scene), agent, check)
    assert result.outcome is Outcome.SUCCESS
    assert agent.threads == {threading.current_thread().name}


class Raising(Agent):
    def act(self, instruction, observation):
        return self.plan_the_next_step()

    def plan_the_next_step(self):
        raise ZeroDivisionError("bug in the agent")


@pytest.mark.parametrize("limit", [0.0, 30.0])
def test_an_agents_exception_keeps_its_traceback_in_the_log_and_the_result(episode, caplog, limit):
    task, ins, scene = episode
    with caplog.at_level(logging.WARNING, logger="muble.episode.loop"):
        result = run_episode(ins, SymbolicWorld(scene), Raising(), check, decision_timeout=limit)
    assert result.outcome is Outcome.AGENT_ERROR and "ZeroDivisionError: bug in the agent" in result.error
    assert "plan_the_next_step" in result.traceback and "Traceback" in result.traceback
    logged = [r for r in caplog.records if r.exc_info]
    assert logged and "plan_the_next_step" in caplog.text, caplog.text
