"""The LLM ledger against the scripted server, symbolic episodes: a second agent on the same ledger sends nothing and
counts the same tokens, cost and latencies; a damaged entry is refused naming its file and stays as it is; a
read-only ledger without a reply names the episode; a sampled reply is recorded with its seed and replayed as
recorded. Then the price table and the cost and latency figures the reports derive (``muble.evaluation.usage``).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from muble import Outcome
from muble.evaluation.stats import quantile
from muble.evaluation.usage import (CACHED_INPUT_TOKENS, COST, INPUT_TOKENS, OUTPUT_TOKENS, PriceTable,
                                    episode_usage, usage_summary)
from muble_plugins.llm.config import LedgerMode
from muble_plugins.llm.endpoint import received
from muble_plugins.llm.ledger import FORMAT, Ledger, LedgerEntryDamaged, checksum, request_key

from tests.llm.chat_server import Reply, ScriptedChatServer, Status
from tests.llm.test_llm_agent import agent_for, episode, oracle_replies

TEMPLATE = "measure_weight_single"
PRICES = dict(price_input_per_mtok=3.0, price_output_per_mtok=15.0, price_date="2025-06-01")
# What differs between an episode asked of the endpoint and the same episode replayed: what this run sent.
SENT = ("requests", "replayed")


@pytest.fixture(scope="module")
def server():
    with ScriptedChatServer() as s:
        yield s


def entries(ledger: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sorted(ledger.rglob("*.json"))}


def recorded_run(server, tmp_path, **options):
    """The oracle's replies to ``TEMPLATE`` asked of the server and recorded in ``tmp_path/ledger``; returns the
    agent, the replies and the ledger keys of the requests in the order they were sent."""
    replies, _ = oracle_replies(TEMPLATE)
    server.play(*[Reply(r) for r in replies], fallback=Status(500, message="nothing more scripted"))
    agent = agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), **PRICES, **options)
    result, _ = episode(agent, TEMPLATE)
    assert result.outcome is Outcome.SUCCESS, result.error
    assert len(server.requests) == len(replies)
    return agent, replies, [request_key(body) for body in server.requests]


def test_a_second_agent_on_the_same_ledger_sends_nothing_and_counts_the_same(server, tmp_path):
    first, replies, _ = recorded_run(server, tmp_path)
    assert len(entries(tmp_path / "ledger")) == len(replies)
    server.play(fallback=Status(500, message="the ledger should have answered"))
    again = agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), **PRICES, log_dir=str(tmp_path / "again"))
    result, _ = episode(again, TEMPLATE)
    assert result.outcome is Outcome.SUCCESS, result.error
    assert server.requests == []  # nothing reached the endpoint
    one, two = first.stats(), again.stats()
    assert two["requests"] == 0 and two["replayed"] == two["replies"] == len(replies)
    assert {k: v for k, v in one.items() if k not in SENT} == {k: v for k, v in two.items() if k not in SENT}
    assert two[COST] == pytest.approx((two[INPUT_TOKENS] * 3.0 + two[OUTPUT_TOKENS] * 15.0) / 1e6) and two[COST] > 0
    assert first.samples() == again.samples()  # each reply's seconds, as recorded
    (log,) = (tmp_path / "again").glob("*.jsonl")
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    assert all(line["replayed"] for line in lines if line["kind"] == "reply")
    assert sum(line["kind"] == "request" for line in lines) == len(replies)  # the dialogue is still shown


def damage_edit(path: Path, other: Path) -> None:
    entry = json.loads(path.read_text())
    entry["reply"]["text"] = '{"stop": true}'  # a plausible reply, but not the one recorded
    path.write_text(json.dumps(entry))


def damage_cut(path: Path, other: Path) -> None:
    path.write_bytes(path.read_bytes()[:100])


def damage_swap(path: Path, other: Path) -> None:
    path.write_bytes(other.read_bytes())  # an intact entry, of another request


@pytest.mark.parametrize("damage,why", [(damage_edit, "does not match its checksum"),
                                        (damage_cut, "cannot be read as JSON"),
                                        (damage_swap, "reply to another request")], ids=["edited", "cut", "swapped"])
def test_a_damaged_entry_is_refused_naming_its_file_and_nothing_is_overwritten(server, tmp_path, damage, why):
    _, _, keys = recorded_run(server, tmp_path)
    ledger = tmp_path / "ledger"
    # The entry of the third request: the first two replay, the third is refused.
    target, other = (Ledger(ledger, LedgerMode.read_write).path(keys[i]) for i in (2, 0))
    damage(target, other)
    before = entries(ledger)
    server.play(fallback=Status(500, message="the ledger should have answered"))
    result, _ = episode(agent_for(server, tmp_path, ledger=str(ledger), **PRICES), TEMPLATE)
    assert result.outcome is Outcome.AGENT_ERROR
    assert f"LLM ledger entry {target} is damaged" in result.error and why in result.error, result.error
    assert result.error.count("ledger entry") == 1  # one error, naming one file
    assert entries(ledger) == before  # the damaged entry is kept as it is, and nothing else was written
    assert server.requests == []  # and nothing was asked in its place


def test_read_only_without_the_reply_names_the_episode_and_sends_nothing(server, tmp_path):
    server.play(fallback=Reply('{"stop": true}'))
    agent = agent_for(server, tmp_path, ledger=str(tmp_path / "empty"), ledger_mode="read_only")
    result, _ = episode(agent, TEMPLATE)
    assert result.outcome is Outcome.AGENT_ERROR and server.requests == []
    assert "agent.ledger_mode=read_only" in result.error and f"({TEMPLATE}), step 1" in result.error, result.error
    assert not (tmp_path / "empty").exists()  # read-only: nothing recorded


def test_read_only_replays_what_is_recorded(server, tmp_path):
    _, replies, _ = recorded_run(server, tmp_path)
    server.play(fallback=Status(500))
    agent = agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), ledger_mode="read_only", **PRICES)
    result, _ = episode(agent, TEMPLATE)
    assert result.outcome is Outcome.SUCCESS and server.requests == [] and agent.stats()["replayed"] == len(replies)


def test_off_sends_every_request_and_records_nothing(server, tmp_path):
    recorded_run(server, tmp_path)
    replies, _ = oracle_replies(TEMPLATE)
    server.play(*[Reply(r) for r in replies])
    agent = agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), ledger_mode="off")
    before = entries(tmp_path / "ledger")
    result, _ = episode(agent, TEMPLATE)
    assert result.outcome is Outcome.SUCCESS and len(server.requests) == len(replies)
    assert entries(tmp_path / "ledger") == before


def test_a_sampled_reply_is_recorded_with_its_seed_and_replayed_as_recorded(server, tmp_path):
    server.play(Reply('{"stop": true}'), fallback=Reply('{"name": "move", "params": {"target": 0}}'))
    agent = agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), temperature=0.7, seed=7)
    episode(agent)
    assert server.requests[0]["seed"] == 7 and server.requests[0]["temperature"] == 0.7
    (path,) = entries(tmp_path / "ledger")
    entry = json.loads(path.read_text())
    assert entry["format"] == FORMAT and entry["seed"] == 7 and entry["sampled"] is True
    assert entry["key"] == request_key(server.requests[0]) and entry["sha256"] == checksum(entry)
    # Asked again, the server would draw another reply; the ledger replays the recorded sample.
    server.play(fallback=Reply('{"name": "move", "params": {"target": 0}}'))
    again = agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), temperature=0.7, seed=7)
    result, _ = episode(again)
    assert server.requests == [] and again.stats()["replayed"] == 1 and result.outcome is not Outcome.AGENT_ERROR
    # Another seed is another request.
    server.play(fallback=Reply('{"stop": true}'))
    episode(agent_for(server, tmp_path, ledger=str(tmp_path / "ledger"), temperature=0.7, seed=8))
    assert len(server.requests) == 1 and len(entries(tmp_path / "ledger")) == 2


def test_an_entry_is_written_once(tmp_path):
    ledger = Ledger(tmp_path, LedgerMode.read_write)
    body = {"model": "m", "messages": [{"role": "user", "content": "hi"}], "temperature": 0.0, "max_tokens": 8}
    reply = {"text": "a", "finish_reason": "stop", INPUT_TOKENS: 3, OUTPUT_TOKENS: 1, CACHED_INPUT_TOKENS: 0,
             "seconds": 0.5}
    key = request_key(body)
    path = ledger.write(key, body, body, reply)
    ledger.write(key, body, body, {**reply, "text": "b"})  # a second worker's reply to the same request
    assert ledger.read(key)["text"] == "a" and list(tmp_path.rglob("*")) == [path.parent, path]
    assert ledger.read(request_key({**body, "temperature": 0.5})) is None  # other settings: another request
    path.write_text("")
    with pytest.raises(LedgerEntryDamaged, match=str(path)):
        ledger.read(key)


def test_cached_tokens_are_read_from_the_completion():
    class Usage:
        prompt_tokens, completion_tokens = 1000, 50
        prompt_tokens_details = type("Details", (), {"cached_tokens": 800})

    class Choice:
        message = type("Message", (), {"content": "{}"})
        finish_reason = "stop"

    completion = type("Completion", (), {"choices": [Choice], "usage": Usage})
    reply = received(completion, 0.25)
    assert (reply.tokens_in, reply.tokens_cached, reply.tokens_out, reply.seconds) == (1000, 800, 50, 0.25)


def test_the_price_table_prices_uncached_cached_and_output_tokens():
    prices = PriceTable(input_per_mtok=3.0, output_per_mtok=15.0, cached_per_mtok=0.3, date="2025-06-01")
    assert prices.cost_usd(1_000_000, 100_000, 800_000) == pytest.approx(0.2 * 3.0 + 0.8 * 0.3 + 0.1 * 15.0)
    assert PriceTable(3.0, 15.0).cost_usd(1_000_000, 0, 800_000) == pytest.approx(3.0)  # no cache price: input's
    assert PriceTable().cost_usd(10**9, 10**9) == 0.0  # a local model
    assert PriceTable.of({"name": "oracle"}) is None
    table = PriceTable.of({"price_input_per_mtok": 2.0, "price_date": "2025-01-02"})
    assert table == PriceTable(2.0, date="2025-01-02")


def test_cost_per_episode_and_success_and_latency_percentiles():
    def record(outcome, tokens_in, tokens_out, cost, latencies):
        return {"outcome": outcome, "agent_stats": {INPUT_TOKENS: tokens_in, OUTPUT_TOKENS: tokens_out, COST: cost,
                                                    "requests": len(latencies), "replayed": 0},
                "agent_samples": {"latency_s": latencies}}

    records = [record("success", 100, 10, 0.5, [1.0, 2.0]), record("timeout", 50, 5, 0.25, [3.0, 10.0]),
               {"outcome": "success", "agent_stats": {"readings": 3}}]  # an agent without tokens: no usage
    usage = usage_summary(records)
    assert usage["episodes"] == 2 and usage["successes"] == 1 and usage[INPUT_TOKENS] == 150
    assert usage[COST] == 0.75 and usage["cost_per_episode_usd"] == 0.375 and usage["cost_per_success_usd"] == 0.75
    assert usage["latency_requests"] == 4 and usage["latency_p50_s"] == 2.5
    assert usage["latency_p95_s"] == pytest.approx(3.0 + 0.85 * 7.0)
    assert usage_summary([records[2]]) is None and episode_usage(records[2]) is None
    assert usage_summary([{**records[1], "outcome": "timeout"}])["cost_per_success_usd"] is None
    assert quantile([], 0.5) is None and quantile([4.0], 0.95) == 4.0 and quantile([1, 2, 3, 10], 0.5) == 2.5
