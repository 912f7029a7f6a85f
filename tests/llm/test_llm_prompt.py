"""What the ``llm`` agent tells the model and how it reads replies: prompt files, a plugin's primitive, the
observation modes, the JSON schema, worked examples, and the report's sums of the agent's counters."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from muble import (ActionCall, Answer, ConfigError, Frame, Observation, ObservationMode, Param, PluginRecord,
                   PrimitiveAction, Track, hookimpl)
from muble.episode.modes import ObservationView
from muble.evaluation.report import OVERALL, agent_lines, summarize
from muble.evaluation.usage import INPUT_TOKENS, OUTPUT_TOKENS
from muble.plugins.manager import make_plugin_manager
from muble.plugins.registry import Registry
from muble_plugins.common.symbolic import SymbolicWorld
from muble_plugins.llm import prompt, reply
from muble_plugins.llm.agent import LlmAgent
from muble_plugins.llm.examples import example_from, pick_examples
from muble_plugins.llm.reply import ReplyError, decision_schema, parse_reply

from tests.episode.test_episode_integrity import instruction_for


class Tap(PrimitiveAction):
    """Touch an object lightly from above."""

    params = (Param("target", "object", required=True), Param("force", "number", low=0.0, high=20.0))


class TapPlugin:
    @hookimpl
    def muble_register_primitives(self):
        return [PluginRecord("tap", Tap, "touch an object lightly from above")]


def test_a_plugins_primitive_is_in_the_prompt_and_the_schema(monkeypatch):
    registry = Registry(make_plugin_manager(extra_plugins=(TapPlugin(),)))
    monkeypatch.setattr(prompt, "get_registry", lambda: registry)
    monkeypatch.setattr(reply, "get_registry", lambda: registry)
    text = prompt.primitives_text(ObservationMode.graph)
    assert "- tap: touch an object lightly from above (target: object id; force: number in [0.0, 20.0], optional)" \
        in text
    names = [alt["properties"]["name"]["enum"][0] for alt in decision_schema(ObservationMode.graph, [0, 1])["anyOf"][:-2]]
    assert "tap" in names
    assert parse_reply('{"name": "tap", "params": {"target": 1, "force": 2.5}}', ObservationMode.graph, [0, 1]) == \
        ActionCall("tap", {"target": 1, "force": 2.5})
    with pytest.raises(ReplyError, match="must be <= 20.0"):
        parse_reply('{"name": "tap", "params": {"target": 1, "force": 99}}', ObservationMode.graph, [0, 1])


def test_a_prompt_files_unknown_placeholder_and_a_missing_file_are_config_errors(tmp_path):
    bad = tmp_path / "system.md"
    bad.write_text("Tools: {{primitivs}}\n")
    with pytest.raises(ConfigError, match=r"unknown placeholder\(s\) \['primitivs'\].*\{\{primitives\}\}"):
        LlmAgent(system_prompt=str(bad))
    with pytest.raises(ConfigError, match="does not exist"):
        LlmAgent(step_prompt=str(tmp_path / "nope.md"))


def test_replies_read_as_decisions():
    ids = [0, 1, 2]
    assert parse_reply('{"stop": true}', ObservationMode.graph, ids) is None
    assert parse_reply('{"answer": [81.5]}', ObservationMode.graph, ids) == Answer([81.5])
    assert parse_reply('Here: {"name": "lift", "params": {"height": 0.1}} done', ObservationMode.graph, ids) == \
        ActionCall("lift", {"height": 0.1})
    assert parse_reply('{"name": "lower"}', ObservationMode.graph, ids) == ActionCall("lower", {})
    assert parse_reply('{"name": "move", "params": {"target": [10, 20]}}', ObservationMode.image, []) == \
        ActionCall("move", {"target": [10, 20]})
    for text, says in (("", "empty"), ('{"stop": false}', "stop"), ('{"answer": 1, "name": "lift"}', "alone"),
                       ('{"name": "lift", "params": [0.1]}', "mapping")):
        with pytest.raises(ReplyError, match=says):
            parse_reply(text, ObservationMode.graph, ids)


def test_the_schema_limits_objects_to_the_scene():
    schema = decision_schema(ObservationMode.graph, [3, 5])
    move = next(a for a in schema["anyOf"] if a["properties"].get("name", {}).get("enum") == ["move"])
    target = move["properties"]["params"]["properties"]["target"]
    assert target["anyOf"][0]["enum"] == [3, 5] and target["anyOf"][1]["enum"][0] == "left"
    assert move["properties"]["params"]["required"] == ["target"]
    pixel = decision_schema(ObservationMode.image, [])["anyOf"][0]["properties"]["params"]["properties"]["target"]
    assert pixel["minItems"] == pixel["maxItems"] == 2


def observation_in(mode: str, template: str = "stack_simple") -> tuple:
    _, ins, scene = instruction_for(template)
    observation = SymbolicWorld(copy.deepcopy(scene)).observe(None, 0)
    observation = Observation(observation.scene, {"front": Frame("front", np.zeros((24, 32, 3), np.uint8))})
    return ins, ObservationView(mode)(observation)


@pytest.mark.parametrize("mode", ["graph", "masks", "image"])
def test_each_observation_mode_is_told_in_its_own_terms(mode):
    ins, seen = observation_in(mode)
    agent = LlmAgent()
    agent.reset(ins, seen, track=Track.program, mode=ObservationMode(mode))
    assert agent.view == mode
    content = agent._step_content(ins, seen)
    if mode == "graph":
        assert isinstance(content, str) and '"colour":' in content and "Name an object by its id" in agent.system
    else:
        text, *images = content
        assert images[1]["image_url"]["url"].startswith("data:image/png;base64,")
        assert '"colour":' not in text["text"]
    if mode == "image":
        assert "pixel [x, y]" in agent.system and "seen only in the images: front 32x24" in content[0]["text"]


def test_the_mode_is_the_one_the_agent_is_told_not_guessed_from_the_objects():
    ins, seen = observation_in("masks")  # objects without words, as masks mode shows them
    agent = LlmAgent()
    agent.reset(ins, seen, track=Track.program, mode=ObservationMode.graph)
    assert agent.view is ObservationMode.graph and "tell them apart in the images" not in agent.system
    agent.reset(ins, seen, track=Track.program, mode=ObservationMode.masks)
    assert "tell them apart in the images" in agent.system


def test_the_language_track_shows_no_program():
    _, seen = observation_in("graph")
    ins, _ = observation_in("graph")
    agent = LlmAgent()
    told = copy.deepcopy(ins)
    told.program = []
    agent.reset(told, seen, track=Track.language, mode=ObservationMode.graph)
    assert "Program:" not in agent._step_content(told, seen)


def test_worked_examples_come_from_ground_truth_sequences_own_template_first():
    record = {"instruction": "How heavy is the blue object?", "template_id": "measure_weight_single",
              "program": [{"type": "scene", "input_value": None}, {"type": "filter_colour", "input_value": "blue"},
                          {"type": "query_weight", "input_value": None}],
              "task": {"task": "query_weight", "target": [81.0]},
              "ground_truth_actions": [["move", {"target": 4}], ["approach_grasp", {"target": 4}], ["lift", {}]]}
    example = example_from(record, scene_file=Path("/nonexistent.json"))  # no scene: no object line
    assert example["decisions"] == [{"name": "move", "params": {"target": 4}},
                                    {"name": "approach", "params": {"target": 4}},  # the original name mapped
                                    {"name": "lift", "params": {}}, {"answer": [81.0]}, {"stop": True}]
    other = {**example, "template": "move_single"}
    assert pick_examples([other, example, other], "measure_weight_single", 2) == [example, other]
    text = prompt.examples_text([example], Track.program)
    assert "Program: scene -> filter_colour(blue) -> query_weight" in text and '{"answer":[81.0]}' in text
    assert "Program:" not in prompt.examples_text([example], Track.language)  # the track, not the data, decides


def test_examples_are_read_from_a_dataset_split(tmp_path):
    from muble.io.layout import DatasetLayout

    layout = DatasetLayout(tmp_path, "train")
    record = {"instruction": "Pick up the red mug.", "template_id": "move_single", "program": [],
              "task": {"task": "pick_up", "target": [0]}, "ground_truth_actions": [["move", {"target": 0}]]}
    for rel, data in ((layout.instruction(0), record),
                      (layout.scene(0), {"objects": [{"colour": "red", "material": "ceramic", "name": "mug"}]})):
        (layout.split_dir / rel).parent.mkdir(parents=True, exist_ok=True)
        (layout.split_dir / rel).write_text(json.dumps(data))
    agent = LlmAgent(examples=1, examples_root=str(tmp_path))
    assert agent.example_pool[0]["objects"] == ["0: red ceramic mug"]
    with pytest.raises(ConfigError, match="no instructions folder"):
        LlmAgent(examples=1, examples_root=str(tmp_path), examples_split="val")
    with pytest.raises(ConfigError, match="needs agent.examples_root"):
        LlmAgent(examples=2)


def test_the_report_sums_agent_counters_with_tokens_per_success_and_parse_failure_rate():
    def record(index, outcome, stats):
        return {"index": index, "template": "move_single", "outcome": outcome, "primitives": [], "timing": None,
                "agent_stats": stats}

    # The first record's token counters have the names of records written before the OpenTelemetry ones.
    records = [record(0, "success", {"tokens_in": 100, "tokens_out": 20, "replies": 4, "parse_failures": 1}),
               record(1, "invalid_action", {INPUT_TOKENS: 50, OUTPUT_TOKENS: 10, "replies": 3, "parse_failures": 3}),
               {**record(2, "success", None)}]
    stats = summarize(records)["agent_stats"][OVERALL]
    assert stats["episodes"] == 2 and stats["totals"][INPUT_TOKENS] == 150
    assert stats["tokens_per_success"] == 180 and stats["parse_failure_rate"] == pytest.approx(4 / 7)
    assert "| overall | 75 | 15 | 180 | 57.1% |" in "\n".join(agent_lines(summarize(records)["agent_stats"]))
    assert summarize([record(0, "success", None)])["agent_stats"] is None
    json.dumps(summarize(records))  # plain data, as report.json holds it
