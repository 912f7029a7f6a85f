"""The ``llm`` agent against a scripted OpenAI-compatible server (real HTTP on 127.0.0.1), symbolic episodes.

With the server replaying the oracle's decisions the agent solves every SHOP-VRB2 template; each way an endpoint
or a model goes wrong (prose, broken JSON, a wrong schema, an unknown primitive, 500, 429 with Retry-After, a hang
past the timeout, a dropped connection) ends in its documented outcome within a bounded time.
"""
from __future__ import annotations

import copy
import json
import time

import pytest

from muble import ActionCall, Agent, Answer, Outcome, get_registry
from muble.app.config import SHOPVRB2_TEMPLATES
from muble.episode import run_episode
from muble.episode.plain import plain
from muble.evaluation.usage import INPUT_TOKENS, OUTPUT_TOKENS
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.success import check
from muble_plugins.common.symbolic import SymbolicWorld
from muble_plugins.llm.agent import LlmAgent

from tests.episode.test_episode_integrity import instruction_for
from tests.llm.chat_server import Drop, Hang, Reply, ScriptedChatServer, Status

BOUND = 20.0  # s: no failure case may take longer than this


class Recorder(Agent):
    """The oracle, its every decision kept."""

    privileged = True

    def __init__(self) -> None:
        self.inner = OracleAgent()
        self.decisions: list = []

    def reset(self, instruction, observation, **told):
        self.inner.reset(instruction, observation, **told)

    def act(self, instruction, observation):
        decision = self.inner.act(instruction, observation)
        self.decisions.append(decision)
        return decision


def as_reply(decision) -> str:
    """A decision as the JSON a model replies with."""
    if isinstance(decision, ActionCall):
        return json.dumps({"name": decision.name, "params": plain(decision.params)})
    if isinstance(decision, Answer):
        return json.dumps({"answer": plain(decision.value)})
    return json.dumps({"stop": True})


def oracle_replies(template: str) -> tuple[list[str], Outcome]:
    """The oracle's decisions on the template's test episode, as replies; the agent asks nothing after an answer."""
    task, ins, scene = instruction_for(template)
    recorder = Recorder()
    result = run_episode(ins, SymbolicWorld(copy.deepcopy(scene)), recorder, check)
    decisions = recorder.decisions
    if len(decisions) >= 2 and isinstance(decisions[-2], Answer) and decisions[-1] is None:
        decisions = decisions[:-1]
    return [as_reply(d) for d in decisions], result.outcome


@pytest.fixture(scope="module")
def server():
    with ScriptedChatServer() as s:
        yield s


def agent_for(server: ScriptedChatServer, tmp_path, **options) -> LlmAgent:
    settings = dict(base_url=server.base_url, timeout=2.0, max_retries=2, http_retries=2, max_backoff=0.2,
                    log_dir=str(tmp_path / "logs"))
    return LlmAgent(**{**settings, **options})


def episode(agent: LlmAgent, template: str = "move_single"):
    task, ins, scene = instruction_for(template)
    start = time.monotonic()
    result = run_episode(ins, SymbolicWorld(copy.deepcopy(scene)), agent, check)
    return result, time.monotonic() - start


@pytest.mark.parametrize("template", SHOPVRB2_TEMPLATES)
@pytest.mark.parametrize("schema", [True, False], ids=["schema", "text"])
def test_replaying_the_oracle_solves_every_template(server, tmp_path, template, schema):
    replies, oracle_outcome = oracle_replies(template)
    assert oracle_outcome is Outcome.SUCCESS
    server.play(*[Reply(r) for r in replies], fallback=Status(500, message="nothing more scripted"))
    agent = agent_for(server, tmp_path, schema=schema)
    result, _ = episode(agent, template)
    assert result.outcome is Outcome.SUCCESS, (result.outcome, result.error)
    assert len(server.requests) == len(replies)
    stats = agent.stats()
    assert stats["requests"] == stats["replies"] == len(replies) and stats["parse_failures"] == 0
    assert stats[INPUT_TOKENS] > 0 and stats[OUTPUT_TOKENS] > 0 and stats["latency_s"] > 0
    assert stats["replayed"] == 0 and stats["cost_usd"] == 0.0  # no ledger outside a run; a local model is free
    assert len(agent.samples()["latency_s"]) == len(replies)
    first = server.requests[0]
    assert ("response_format" in first) is schema
    # The prompt names the episode's instruction and lists every registered primitive.
    system, step = first["messages"][0]["content"], first["messages"][1]["content"]
    assert all(f"- {name}:" in system for name in get_registry().names("primitive"))
    _, ins, _ = instruction_for(template)
    assert ins.instruction in step and "Program: scene" in step
    # Every request and reply is in the episode's log.
    (log,) = (tmp_path / "logs").glob("*.jsonl")
    kinds = [json.loads(line)["kind"] for line in log.read_text().splitlines()]
    assert kinds.count("request") == kinds.count("reply") == len(replies) and kinds[0] == "episode"


def test_the_schema_goes_in_the_form_the_server_takes(server, tmp_path):
    server.play(fallback=Reply('{"stop": true}'))
    episode(agent_for(server, tmp_path, schema_form="json_object"))
    form = server.requests[0]["response_format"]
    assert form["type"] == "json_object" and "anyOf" in form["schema"]
    server.play(fallback=Reply('{"stop": true}'))
    episode(agent_for(server, tmp_path))
    form = server.requests[0]["response_format"]
    assert form["type"] == "json_schema" and "anyOf" in form["json_schema"]["schema"]


def test_the_history_reports_results_and_is_bounded(server, tmp_path):
    replies, _ = oracle_replies("stack_simple")
    server.play(*[Reply(r) for r in replies])
    result, _ = episode(agent_for(server, tmp_path, history=2), "stack_simple")
    assert result.outcome is Outcome.SUCCESS
    last = server.requests[-1]["messages"][1]["content"]
    assert "earlier steps not shown" in last and "-> ok" in last
    assert last.count("-> ok") == 2


def unusable_case(server, tmp_path, text: str) -> tuple:
    server.play(fallback=Reply(text))
    agent = agent_for(server, tmp_path)
    result, seconds = episode(agent)
    return result, seconds, agent.stats()


@pytest.mark.parametrize("text,kind,reason", [
    ("I would first move the gripper above the mug, then grasp it.", "no JSON object", "no JSON object"),
    ('{"name": "move", "params": {"target": 1', "JSON that does not parse", "does not parse"),
    ('{"action": "move", "object": 1}', "another shape", "expected"),
    ('{"name": "teleport", "params": {"target": 1}}', "unknown primitive", "unknown primitive"),
    ('{"name": "move", "params": {"target": 99}}', "invalid parameters", "not in the scene"),
], ids=["prose", "broken_json", "wrong_schema", "unknown_primitive", "unknown_object"])
def test_an_unusable_reply_is_asked_again_then_ends_as_invalid_action(server, tmp_path, text, kind, reason):
    result, seconds, stats = unusable_case(server, tmp_path, text)
    assert result.outcome is Outcome.INVALID_ACTION, (result.outcome, result.error)
    assert f"{kind} in 3 replies" in result.error and seconds < BOUND
    assert stats["parse_failures"] == 3 and stats["reasks"] == 2 and stats["invalid_end"] == 1
    # The re-ask carries the error back to the model; the log has the whole reason.
    retry = server.requests[-1]["messages"]
    assert retry[-2] == {"role": "assistant", "content": text} and reason in retry[-1]["content"]
    (log,) = (tmp_path / "logs").glob("*.jsonl")
    unusable = [json.loads(line) for line in log.read_text().splitlines() if '"unusable"' in line]
    assert len(unusable) == 3 and reason in unusable[-1]["error"]


def test_a_reply_corrected_after_a_re_ask_goes_on(server, tmp_path):
    replies, _ = oracle_replies("measure_weight_single")
    server.play(Reply("Sure! Here is the JSON: {broken"), *[Reply(r) for r in replies])
    agent = agent_for(server, tmp_path)
    result, _ = episode(agent, "measure_weight_single")
    assert result.outcome is Outcome.SUCCESS and agent.stats()["parse_failures"] == 1


def test_prose_around_the_json_object_is_ignored(server, tmp_path):
    replies, _ = oracle_replies("move_single")
    server.play(*[Reply(f"Next I act.\n```json\n{r}\n```\nThat is all.") for r in replies])
    result, _ = episode(agent_for(server, tmp_path, schema=False))
    assert result.outcome is Outcome.SUCCESS


def test_http_500_is_retried_then_ends_as_agent_error(server, tmp_path):
    server.play(fallback=Status(500))
    agent = agent_for(server, tmp_path)
    result, seconds = episode(agent)
    assert result.outcome is Outcome.AGENT_ERROR and "HTTP 500 after 3 tries" in result.error
    assert seconds < BOUND and agent.stats()["http_retries"] == 2 and len(server.requests) == 3


def test_a_passing_500_is_retried(server, tmp_path):
    replies, _ = oracle_replies("move_single")
    server.play(Status(503), *[Reply(r) for r in replies])
    agent = agent_for(server, tmp_path)
    result, _ = episode(agent)
    assert result.outcome is Outcome.SUCCESS and agent.stats()["http_retries"] == 1


def test_429_waits_what_retry_after_asks(server, tmp_path):
    replies, _ = oracle_replies("move_single")
    server.play(Status(429, {"Retry-After": "1"}, "rate limited"), *[Reply(r) for r in replies])
    agent = agent_for(server, tmp_path, max_backoff=5.0)
    result, seconds = episode(agent)
    assert result.outcome is Outcome.SUCCESS and agent.stats()["http_retries"] == 1
    assert 1.0 <= seconds < BOUND


def test_429_that_persists_ends_as_agent_error(server, tmp_path):
    server.play(fallback=Status(429, {"Retry-After": "0.1"}))
    result, seconds = episode(agent_for(server, tmp_path))
    assert result.outcome is Outcome.AGENT_ERROR and "HTTP 429" in result.error and seconds < BOUND


def test_a_hang_past_the_timeout_ends_as_agent_error(server, tmp_path):
    server.play(fallback=Hang(10.0))
    agent = agent_for(server, tmp_path, timeout=0.5)
    result, seconds = episode(agent)
    assert result.outcome is Outcome.AGENT_ERROR and "within 0.5 s" in result.error
    assert seconds < 5.0 and agent.stats()["timeouts"] == 1 and len(server.requests) == 1


def test_a_dropped_connection_is_retried_then_ends_as_agent_error(server, tmp_path):
    server.play(fallback=Drop())
    agent = agent_for(server, tmp_path)
    result, seconds = episode(agent)
    assert result.outcome is Outcome.AGENT_ERROR and "connection failed" in result.error
    assert seconds < BOUND and len(server.requests) == 3


def test_a_client_error_is_not_retried(server, tmp_path):
    server.play(fallback=Status(400, message="response_format is not supported"))
    result, _ = episode(agent_for(server, tmp_path))
    assert result.outcome is Outcome.AGENT_ERROR and "HTTP 400" in result.error and len(server.requests) == 1
    assert "agent.schema_form" in result.error


def test_the_key_is_sent_but_never_logged(server, tmp_path, monkeypatch):
    monkeypatch.setenv("MUBLE_TEST_LLM_KEY", "sk-secret-123")
    server.play(fallback=Reply('{"stop": true}'))
    agent = agent_for(server, tmp_path, api_key_env="MUBLE_TEST_LLM_KEY")
    episode(agent)
    assert server.authorizations == ["Bearer sk-secret-123"]
    (log,) = (tmp_path / "logs").glob("*.jsonl")
    assert "sk-secret-123" not in log.read_text()
    assert "sk-secret-123" not in json.dumps(agent.stats())
