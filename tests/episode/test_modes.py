"""Tracks and observation modes with real physics and rendering: what an agent is given in each, pixel targets.

One generated episode is run in the three modes by an agent that records everything it is given; the oracle
(privileged, acting through pixels in ``image`` mode) solves it in each.
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from omegaconf import OmegaConf

from muble import ActionCall, Agent, ObservationMode, Outcome, get_registry
from muble.core.types import Frame, Observation
from muble.episode.modes import ObservationView, resolve_pixels, visible_pixel

ATTRIBUTES = ("model", "name", "shape", "size", "material", "colour")


def strings_and_keys(value, out=None):
    """Every string and every mapping key inside ``value`` (dataclasses, mappings, sequences; arrays skipped)."""
    out = out if out is not None else {"strings": [], "keys": []}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            strings_and_keys(getattr(value, f.name), out)
    elif isinstance(value, dict):
        for k, v in value.items():
            out["keys"].append(k)
            strings_and_keys(k, out)
            strings_and_keys(v, out)
    elif isinstance(value, (list, tuple)):
        for v in value:
            strings_and_keys(v, out)
    elif isinstance(value, str):
        out["strings"].append(value)
    return out


class Recorder(Agent):
    """Records every instruction and observation it is given; tries one primitive, then stops."""

    def __init__(self):
        self.given: list[tuple] = []
        self.told: tuple | None = None

    def reset(self, instruction, observation, *, track, mode):
        self.given = [(instruction, observation)]
        self.told = (track, mode)

    def act(self, instruction, observation):
        self.given.append((instruction, observation))
        return ActionCall("lift") if len(self.given) == 2 else None


def test_pixel_targets_resolve_to_the_object_seen_there():
    from muble.core.scene import SceneGraph, SceneObject

    seg = np.full((6, 8), -2, dtype=np.int32)  # table
    seg[1:4, 2:5] = 7
    obj = SceneObject(id=7, model="m", name="mug", shape="s", size="small", material="glass", colour="red",
                      position=np.zeros(3), orientation=np.array([1.0, 0, 0, 0]), weight_gt=None, stackable=False,
                      stack_base=False, pickupable=True)
    obs = Observation(scene=SceneGraph(objects=[obj]),
                      images={"front": Frame("front", np.zeros((6, 8, 3), np.uint8), segmentation=seg)})
    declared = get_registry().get("primitive", "approach").record.factory.params
    assert resolve_pixels(ActionCall("approach", {"target": [3, 2]}), obs, declared).params["target"] == 7
    assert resolve_pixels(ActionCall("approach", {"target": {"pixel": [2, 1], "camera": "front"}}), obs,
                          declared).params["target"] == 7
    assert "shows no object" in resolve_pixels(ActionCall("approach", {"target": [0, 0]}), obs, declared)
    assert "outside" in resolve_pixels(ActionCall("approach", {"target": [8, 0]}), obs, declared)
    assert "pixel" in resolve_pixels(ActionCall("approach", {"target": 7}), obs, declared)  # ids are not shown
    assert resolve_pixels(ActionCall("move", {"target": "left"}), obs,
                          get_registry().get("primitive", "move").record.factory.params).params["target"] == "left"
    x, y = visible_pixel(obs.images["front"], 7)
    assert seg[y, x] == 7
    # Image mode shows no object and no segmentation; graph mode leaves the observation alone.
    view = ObservationView("image")(obs)
    assert view.scene.objects == [] and view.images["front"].segmentation is None
    assert ObservationView("graph")(obs) is obs


def test_each_mode_view_crosses_plain_data_as_it_was_given():
    """What Gymnasium and ``muble serve`` carry: each mode's view turned to plain JSON data and back is the view the
    agent was given (masks mode: ids, poses and masks, the attribute words still withheld; image mode: no objects)."""
    import json

    from muble.core.scene import SceneGraph, SceneObject
    from muble.episode.plain import observation_from_plain, observation_to_plain

    seg = np.full((6, 8), -2, dtype=np.int32)
    seg[1:4, 2:5] = 7
    obj = SceneObject(id=7, model="m", name="mug", shape="s", size="small", material="glass", colour="red",
                      position=np.array([0.4, 0.1, 0.0]), orientation=np.array([1.0, 0, 0, 0]), weight_gt=None,
                      stackable=False, stack_base=False, pickupable=True, explicit_id=True)
    obs = Observation(scene=SceneGraph(objects=[obj]), measurements={"weight": {7: 120.0}},
                      images={"front": Frame("front", np.zeros((6, 8, 3), np.uint8), segmentation=seg)})
    for mode in ("graph", "masks", "image"):
        view = ObservationView(mode)(obs)
        back = observation_from_plain(json.loads(json.dumps(observation_to_plain(view))))
        assert [o.id for o in back.scene.objects] == [o.id for o in view.scene.objects]
        for mine, theirs in zip(back.scene.objects, view.scene.objects):
            assert [getattr(mine, a) for a in ATTRIBUTES] == [getattr(theirs, a) for a in ATTRIBUTES]
            assert mine.pickupable == theirs.pickupable and mine.weight_gt is None
            assert np.allclose(mine.position, theirs.position)
            assert (mine.mask is None) == (theirs.mask is None)
            if mine.mask is not None:
                assert mine.mask.to_dict() == theirs.mask.to_dict()
        if mode == "masks":
            assert back.scene.objects[0].name is None and back.scene.objects[0].model is None
        if mode == "image":
            assert back.scene.objects == []


@pytest.mark.slow
def test_each_mode_gives_only_what_it_says_and_the_oracle_solves_each():
    from muble.app.config import compose
    from muble.episode.components import episode_runner, scene_generator
    from muble.evaluation.episodes import build_components

    base = ["agent=oracle", "output.dir=/tmp", "dataset.root=/tmp", "renderer.width=160", "renderer.height=120",
            "renderer.shadows=false"]
    cfg = compose("eval", base)
    task = get_registry().create("task", "stack_weight", {})
    components = build_components({**OmegaConf.to_container(cfg, resolve=True), "benchmark": {"mode": "image"}})
    generator = scene_generator(cfg, components["object_set"])
    try:
        for index in range(40):
            scene = generator.generate(index)
            found = task.generate(scene, np.random.default_rng([0, index, 1]))
            if found:
                break
    finally:
        generator.close()
    instruction = found[0]
    words = {str(getattr(o, a)) for o in scene.objects for a in ATTRIBUTES if getattr(o, a)}
    for mode in ("graph", "masks", "image"):
        for track in ("program", "language"):
            run_cfg = compose("eval", [*base, f"benchmark.mode={mode}", f"benchmark.track={track}"])
            runner = episode_runner(run_cfg, components)
            if track == "program":  # the oracle (privileged) solves the episode through the mode's action form
                result = runner.execute(scene, instruction, task).result
                assert result.outcome is Outcome.SUCCESS, (mode, [str(a) for a in result.actions], result.error)
            recorder = runner.agent = Recorder()
            runner.execute(scene, instruction, task)
            assert len(recorder.given) == 3  # reset, the first act, the act after the primitive
            assert recorder.told == (track, mode) and isinstance(recorder.told[1], ObservationMode)
            for told, observation in recorder.given:
                assert (told.program == []) == (track == "language")
                assert all(step.get("input") is None and "output" not in step for step in told.program)
                found_words = set(strings_and_keys(observation)["strings"]) & words
                if mode == "graph":
                    continue
                assert not found_words, (mode, found_words)
                assert all(f.depth is not None for f in observation.images.values())
                if mode == "image":
                    seen = strings_and_keys(observation)
                    assert observation.scene.objects == []
                    assert all(f.segmentation is None for f in observation.images.values())
                    assert not [k for k in seen["keys"] if isinstance(k, (int, np.integer))], seen["keys"]
                    assert not [s for s in seen["strings"] if re.search(r"\bobjects?\s*[=:]?\s*\[?\d", s)]
                else:
                    assert {o.id for o in observation.scene.objects} == set(scene.ids)
                    assert all(o.mask is not None for o in observation.scene.objects)
            # The primitive's result reaches the agent in every mode.
            assert recorder.given[2][1].last_result is not None


def test_the_instruction_told_on_either_track_holds_no_ground_truth_record():
    """A stored instruction's records beside its text and program (the ground-truth actions, the task's target,
    the scene samples drawn) reach no agent, on either track: one function (``track_instruction`` on
    ``muble.core.observation.agent_instruction``) makes what the loop, Gymnasium and the remote server hand out."""
    from muble.dataset.protocol import load_protocol, shipped_files
    from muble.episode.modes import track_instruction
    from muble.io.instructions_io import instruction_from_dict

    files = shipped_files(load_protocol("shopvrb2_v2"), "mini")
    rel = next(k for k in sorted(files) if "/instructions/" in k)
    import json

    stored = instruction_from_dict(json.loads(files[rel]))
    assert {"task", "ground_truth_actions"} <= set(stored.extra)
    for track in ("program", "language"):
        told = track_instruction(stored, track)
        assert told.extra == {} and told.instruction == stored.instruction
        assert all(step.get("output") is None for step in told.program)
    assert track_instruction(stored, "language").program == []
