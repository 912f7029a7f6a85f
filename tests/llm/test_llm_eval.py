"""``muble eval agent=llm`` with physics against the scripted server: the oracle's physics decisions replayed solve
the episode, the records carry the agent's counters, the report sums them and the request logs land beside the
records; a multirun over two prompt files runs and ``muble compare`` summarises it."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from muble_plugins.llm import prompt

from tests.app.test_app_eval import muble
from tests.llm.chat_server import Reply, ScriptedChatServer

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
    assert overall["tokens_per_success"] == stats["tokens_in"] + stats["tokens_out"]
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
