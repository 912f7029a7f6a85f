"""``muble eval agent=llm`` with physics against the scripted server: the oracle's physics decisions replayed solve
the episode, the records carry the agent's counters, the report sums them and the request logs land beside the
records; a multirun over two prompt files runs and ``muble compare`` summarises it.

Then the LLM ledger: the same run again from a run's ledger sends no request and writes the same records; a run
killed mid-episode and resumed counts the tokens and cost of an uninterrupted one; a damaged entry ends its episode
naming the file, which stays as it is; a read-only ledger without a reply names the episode; and the cost in
report.json, summary.md, ``muble compare`` and the site is the tokens at the price table.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from muble.evaluation.usage import COST, INPUT_TOKENS, OUTPUT_TOKENS, dollars
from muble_plugins.llm import prompt

from tests.app.test_app_eval import muble
from tests.llm.chat_server import Hang, Reply, ScriptedChatServer, Status

TEMPLATE = "measure_weight_single"  # five primitives and an answer: the quickest template with a query


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """One val scene with its ground-truth sequence (the oracle's decisions in physics, recorded by generate)."""
    root = tmp_path_factory.mktemp("llm_eval") / "ds"
    result = muble("generate", "dataset.splits=[val]", "dataset.sizes=[1]", f"dataset.root={root}",
                   "dataset.executor=serial", f"dataset.templates=[{TEMPLATE}]", "renderer.width=96",
                   "renderer.height=64", f"hydra.run.dir={root.parent / 'gen'}")
    assert result.returncode == 0, result.stderr[-2000:]
    return root


def oracle_replies(root: Path) -> list[Reply]:
    """The stored ground-truth primitives of index 0 as JSON replies, then its answer (the query's recorded
    target)."""
    (file,) = (root / "val" / "instructions").glob("*.json")
    record = json.loads(file.read_text())
    replies = [Reply(json.dumps({"name": name, "params": params})) for name, params in record["ground_truth_actions"]]
    return replies + [Reply(json.dumps({"answer": record["task"]["target"]}))]


@pytest.fixture(scope="module")
def server():
    with ScriptedChatServer() as s:
        yield s


@pytest.mark.slow
def test_eval_replaying_the_oracle_in_physics(dataset, server, tmp_path):
    replies = oracle_replies(dataset)
    server.play(*replies)
    out = tmp_path / "run"
    result = muble("eval", "agent=llm", f"agent.base_url={server.base_url}", "agent.timeout=30",
                   f"dataset.root={dataset}", "dataset.executor=serial", f"hydra.run.dir={out}")
    assert result.returncode == 0, result.stderr[-2000:]
    (record,) = [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines()]
    assert record["outcome"] == "success", record
    stats = record["agent_stats"]
    assert stats["requests"] == stats["replies"] == len(replies) and stats["parse_failures"] == 0
    overall = json.loads((out / "report.json").read_text())["splits"]["val"]["agent_stats"]["overall"]
    assert overall["tokens_per_success"] == stats[INPUT_TOKENS] + stats[OUTPUT_TOKENS]
    assert overall["parse_failure_rate"] == 0.0
    assert "tokens / success" in (out / "summary.md").read_text()
    (log,) = (out / "llm_logs").glob("*.jsonl")  # beside the records
    assert sum(json.loads(line)["kind"] == "reply" for line in log.read_text().splitlines()) == len(replies)


@pytest.mark.slow
def test_a_multirun_over_two_prompt_files_with_a_summary(dataset, server, tmp_path):
    prompts = []
    for name, extra in (("plain", ""), ("careful", "Check every object's words against the instruction.\n")):
        path = tmp_path / f"{name}.md"
        path.write_text((prompt.PROMPTS / "system.md").read_text() + extra)
        prompts.append(path)
    server.play(fallback=Reply('{"stop": true}'))  # each episode stops at once: the sweep is what is tested
    sweep = tmp_path / "sweep"
    result = muble("eval", "-m", "agent=llm", f"agent.system_prompt={prompts[0]},{prompts[1]}",
                   f"agent.base_url={server.base_url}", f"dataset.root={dataset}", "dataset.executor=serial",
                   f"hydra.sweep.dir={sweep}")
    assert result.returncode == 0, result.stderr[-2000:]
    runs = sorted(p.parent for p in sweep.glob("*/results.json"))
    assert len(runs) == 2
    used = {json.loads((run / "results.json").read_text())["agent_config"]["system_prompt"] for run in runs}
    assert used == {str(p) for p in prompts}
    # The summary: both prompts' runs side by side on the same episode.
    compared = muble("compare", *map(str, runs), "--out", str(tmp_path / "compare"))
    assert compared.returncode == 0, compared.stderr[-2000:]
    table = json.loads((tmp_path / "compare" / "compare.json").read_text())
    assert [r["label"] for r in table["runs"]] == ["0", "1"]
    shutil.rmtree(sweep)


# --- the LLM ledger and costs ------------------------------------------------------------------------------------
PRICES = {"input": 3.0, "output": 15.0}  # USD per million tokens
PRICE_OPTIONS = (f"agent.price_input_per_mtok={PRICES['input']}", f"agent.price_output_per_mtok={PRICES['output']}",
                 "agent.price_date=2025-06-01")
# What a run sends, beside what its episodes used: a replayed reply sends no request.
SENT = ("requests", "replayed")


def llm_eval_args(server: ScriptedChatServer, dataset: Path, out: Path, *overrides: str) -> list[str]:
    return ["eval", "agent=llm", f"agent.base_url={server.base_url}", "agent.timeout=30", *PRICE_OPTIONS,
            f"dataset.root={dataset}", "dataset.executor=serial", f"hydra.run.dir={out}", *overrides]


def llm_eval(server: ScriptedChatServer, dataset: Path, out: Path, *overrides: str) -> dict:
    """Evaluate into ``out``; returns its one record."""
    result = muble(*llm_eval_args(server, dataset, out, *overrides))
    assert result.returncode == 0, result.stderr[-2000:]
    (record,) = [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines()]
    return record


def entries(ledger: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sorted(ledger.rglob("*.json"))}


def priced(stats: dict) -> float:
    """The tokens of ``stats`` at ``PRICES`` (the scripted server reports no cached tokens)."""
    return (stats[INPUT_TOKENS] * PRICES["input"] + stats[OUTPUT_TOKENS] * PRICES["output"]) / 1e6


@pytest.fixture(scope="module")
def recorded(dataset, server, tmp_path_factory) -> tuple[Path, dict, int]:
    """A run that asked the endpoint every request and recorded the replies in its ledger: its folder, record and
    number of replies."""
    replies = oracle_replies(dataset)
    server.play(*replies, fallback=Status(500, message="nothing more scripted"))
    out = tmp_path_factory.mktemp("recorded") / "run"
    record = llm_eval(server, dataset, out)
    assert record["outcome"] == "success" and len(server.requests) == len(replies)
    assert len(entries(out / "llm_ledger")) == len(replies)
    return out, record, len(replies)


# Fields of a record that say how and where its run ran, not what the episode did.
EXECUTION = ("timing", "platform")


def comparable(record: dict) -> dict:
    """A record less its timing, the machine it ran on and what its run sent (requests, replayed)."""
    stats = {k: v for k, v in record["agent_stats"].items() if k not in SENT}
    return {**{k: v for k, v in record.items() if k not in EXECUTION}, "agent_stats": stats}


@pytest.mark.slow
def test_a_run_again_from_the_ledger_sends_nothing_and_writes_the_same_records(dataset, server, recorded, tmp_path):
    first, one, replies = recorded
    server.play(fallback=Status(500, message="the ledger should have answered"))
    again = tmp_path / "again"
    two = llm_eval(server, dataset, again, f"agent.ledger={first / 'llm_ledger'}")
    assert server.requests == []  # counted at the server: no request reached the endpoint
    assert (one["agent_stats"]["requests"], one["agent_stats"]["replayed"]) == (replies, 0)
    assert (two["agent_stats"]["requests"], two["agent_stats"]["replayed"]) == (0, replies)
    assert comparable(two) == comparable(one)
    assert not (again / "llm_ledger").exists()  # the shared ledger held every reply: nothing new to record

    # The cost in every report is the tokens at the price table.
    cost = priced(one["agent_stats"])
    assert cost > 0 and one["agent_stats"][COST] == pytest.approx(cost)
    for run in (first, again):
        report = json.loads((run / "report.json").read_text())
        usage = report["splits"]["val"]["agent_stats"]["overall"]["usage"]
        assert usage[COST] == pytest.approx(cost) and usage["cost_per_success_usd"] == pytest.approx(cost)
        assert usage[INPUT_TOKENS] == one["agent_stats"][INPUT_TOKENS] and usage["latency_requests"] == replies
        assert usage["latency_p50_s"] <= usage["latency_p95_s"]
        assert report["prices"] == {"input_per_mtok": 3.0, "output_per_mtok": 15.0, "cached_per_mtok": 3.0,
                                    "date": "2025-06-01"}
        summary = (run / "summary.md").read_text()
        assert f"| {dollars(cost)} |" in summary and "read 2025-06-01" in summary
    compared = muble("compare", str(first), str(again), "--out", str(tmp_path / "compare"))
    assert compared.returncode == 0, compared.stderr[-2000:]
    usage = json.loads((tmp_path / "compare" / "compare.json").read_text())["usage"]
    assert usage["run"][COST] == pytest.approx(cost) and usage["again"][COST] == pytest.approx(cost)
    assert (usage["run"]["requests"], usage["again"]["replayed"]) == (replies, replies)
    assert dollars(cost) in compared.stdout and dollars(cost) in (tmp_path / "compare" / "compare.md").read_text()
    site = muble("site", str(first), "--out", str(tmp_path / "site"))
    assert site.returncode == 0, site.stderr[-2000:]
    board = (tmp_path / "site" / "index.html").read_text()
    assert "cost per success" in board and dollars(cost) in board and "latency p50 / p95" in board


@pytest.mark.slow
def test_a_resumed_run_counts_the_tokens_and_cost_of_an_uninterrupted_one(dataset, server, recorded, tmp_path):
    first, one, replies = recorded
    scripted = oracle_replies(dataset)
    done = 3  # replies the endpoint gives before the run is killed, waiting for the next
    server.play(*scripted[:done], fallback=Hang(20.0))
    out = tmp_path / "resumed"
    env = {**os.environ, "HYDRA_FULL_ERROR": "0", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    run = subprocess.Popen([sys.executable, "-m", "muble.app.cli", *llm_eval_args(server, dataset, out)], env=env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240
        while len(server.requests) <= done and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert len(server.requests) == done + 1, "the run did not reach its hanging request"
    finally:
        run.kill()
        run.wait(timeout=30)
    assert len(entries(out / "llm_ledger")) == done
    assert not (out / "episodes_val.jsonl").exists() or not (out / "episodes_val.jsonl").read_text().strip()

    server.play(*scripted[done:], fallback=Status(500, message="nothing more scripted"))
    resumed = llm_eval(server, dataset, out)  # the same command into the same folder
    assert len(server.requests) == replies - done
    assert (resumed["agent_stats"]["requests"], resumed["agent_stats"]["replayed"]) == (replies - done, done)
    for key in (INPUT_TOKENS, OUTPUT_TOKENS, COST, "replies"):
        assert resumed["agent_stats"][key] == one["agent_stats"][key], key
    usage = [json.loads((run_dir / "report.json").read_text())["splits"]["val"]["agent_stats"]["overall"]["usage"]
             for run_dir in (first, out)]
    for key in (INPUT_TOKENS, OUTPUT_TOKENS, COST, "cost_per_episode_usd", "cost_per_success_usd"):
        assert usage[1][key] == usage[0][key], key


@pytest.mark.slow
def test_a_damaged_entry_ends_its_episode_naming_the_file_and_nothing_is_overwritten(dataset, server, recorded,
                                                                                      tmp_path):
    first, _, _ = recorded
    ledger = tmp_path / "ledger"
    shutil.copytree(first / "llm_ledger", ledger)
    damaged = next(iter(entries(ledger)))  # every request is replayed in turn, so any entry is reached
    entry = json.loads(damaged.read_text())
    entry["reply"]["text"] = '{"stop": true}'
    damaged.write_text(json.dumps(entry))
    before = entries(ledger)
    server.play(fallback=Status(500, message="the ledger should have answered"))
    record = llm_eval(server, dataset, tmp_path / "run", f"agent.ledger={ledger}")  # the evaluation finishes
    assert record["outcome"] == "agent_error" and server.requests == []
    assert f"LLM ledger entry {damaged} is damaged" in record["error"], record["error"]
    assert record["error"].count("ledger entry") == 1
    assert entries(ledger) == before  # kept as it is; nothing written over it or beside it


@pytest.mark.slow
def test_read_only_without_the_reply_names_the_episode(dataset, server, tmp_path):
    server.play(fallback=Reply('{"stop": true}'))
    record = llm_eval(server, dataset, tmp_path / "run", "agent.ledger_mode=read_only",
                      f"agent.ledger={tmp_path / 'empty'}")
    assert record["outcome"] == "agent_error" and server.requests == []
    assert "episode val 0 (measure_weight_single), step 1" in record["error"], record["error"]
