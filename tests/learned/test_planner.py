"""The learned planner: ``muble train trainer=planner`` end to end, determinism, resuming, refusals, and a small
trained planner solving symbolic episodes it never saw."""
from __future__ import annotations

import json

import pytest

torch = pytest.importorskip("torch")

from muble import Outcome  # noqa: E402
from muble.app.cli import main as muble_main  # noqa: E402
from muble.core.errors import ConfigError  # noqa: E402
from muble.core.training import TrainingRun  # noqa: E402

from muble_plugins.common.episodes import run_symbolic_episode  # noqa: E402
from muble_plugins.learned import checkpoint as ck  # noqa: E402
from muble_plugins.learned.agent import LearnedPlannerAgent  # noqa: E402
from muble_plugins.learned.planner import PlannerTrainer, instructions_for, scene_for  # noqa: E402


@pytest.fixture(autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def _run(out, seed=0, resume=True) -> TrainingRun:
    return TrainingRun(out_dir=out, seed=seed, resume=resume, record={"config": {"train": {}}}, progress=False,
                       threads=1)


def _weights(path):
    return ck.load(path, "planner")["state"]["model"]


def _same(a, b) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_train_from_the_command_line_then_the_agent_plays_the_checkpoint(tmp_path, clear_hydra, capsys):
    out = tmp_path / "planner"
    assert muble_main(["train", "trainer=planner", "trainer.scenes=30", "trainer.epochs=1",
                       "trainer.validation_scenes=2", "train.threads=1", "train.progress=false",
                       f"train.out_dir={out}"]) == 0
    figures = json.loads((out / "train.json").read_text())["figures"]
    for key in ("data_s", "train_s", "train_accuracy", "validation_accuracy", "symbolic_success"):
        assert key in figures
    assert figures["train_samples"] > 1000 and figures["epochs"] == 1
    assert "symbolic_success:" in capsys.readouterr().out
    payload = ck.load(out / "planner.pt", "planner")
    assert payload["epoch"] == 1 and payload["record"]["config"]["trainer"]["scenes"] == 30
    # The agent loads what was written and plays an episode to its end (one epoch: solving is not expected).
    agent = LearnedPlannerAgent(checkpoint=str(out / "planner.pt"))
    scene = scene_for(99, 0, True)
    instruction = instructions_for(scene, 99, 0, True)[0]
    result = run_symbolic_episode(instruction, scene, agent)
    assert result.outcome is not Outcome.AGENT_ERROR, result.error


def test_same_seed_same_weights_and_another_seed_others(tmp_path):
    settings = {"scenes": 5, "epochs": 1, "validation_scenes": 0}
    for name, seed in (("a", 3), ("b", 3), ("c", 4)):
        PlannerTrainer(**settings).train(_run(tmp_path / name, seed))
    a, b, c = (_weights(tmp_path / name / "planner.pt") for name in "abc")
    assert _same(a, b)
    assert not _same(a, c)


def test_a_stopped_run_resumes_to_the_weights_of_an_unstopped_one(tmp_path, monkeypatch):
    settings = {"scenes": 5, "epochs": 3, "validation_scenes": 0}
    PlannerTrainer(**settings).train(_run(tmp_path / "whole"))
    saves = []
    real_save = ck.save

    class Stopped(Exception):
        pass

    def stop_after_first_epoch(*args, **kwargs):
        saves.append(args[4])
        real_save(*args, **kwargs)
        if args[4] == 1:
            raise Stopped

    monkeypatch.setattr(ck, "save", stop_after_first_epoch)
    with pytest.raises(Stopped):
        PlannerTrainer(**settings).train(_run(tmp_path / "stopped"))
    assert ck.load(tmp_path / "stopped" / "planner.pt", "planner")["epoch"] == 1
    saves.clear()
    PlannerTrainer(**settings).train(_run(tmp_path / "stopped"))
    assert saves[0] == 2  # went on with the second epoch
    assert _same(_weights(tmp_path / "whole" / "planner.pt"), _weights(tmp_path / "stopped" / "planner.pt"))


def test_a_checkpoint_of_other_settings_is_refused_and_a_missing_one_named(tmp_path):
    PlannerTrainer(scenes=4, epochs=1, validation_scenes=0).train(_run(tmp_path / "run"))
    with pytest.raises(ConfigError, match="other settings"):
        PlannerTrainer(scenes=4, epochs=1, validation_scenes=0, learning_rate=0.01).train(_run(tmp_path / "run"))
    with pytest.raises(ConfigError, match="no planner checkpoint"):
        LearnedPlannerAgent(checkpoint=str(tmp_path / "nothing.pt"))
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ConfigError, match="not a readable checkpoint"):
        LearnedPlannerAgent(checkpoint=str(tmp_path / "junk.pt"))


def test_a_checkpoint_trained_under_other_hidden_properties_is_refused_naming_them(tmp_path):
    """The checkpoint records its classes and the properties its features name; a planner trained where a package
    added a property cannot be played without it (its outputs would mean other primitives)."""
    PlannerTrainer(scenes=2, epochs=1, validation_scenes=0).train(_run(tmp_path / "run"))
    path = tmp_path / "run" / "planner.pt"
    payload = torch.load(path, map_location="cpu", weights_only=False)
    assert payload["extra"]["layout"]["properties"] == ["weight", "stiffness", "friction", "com_offset", "rattles"]
    assert payload["extra"]["layout"]["classes"][-1] == "stop"
    LearnedPlannerAgent(checkpoint=str(path))  # as trained: accepted
    payload["extra"]["layout"]["properties"].append("temperature")
    payload["extra"]["layout"]["classes"].insert(-1, "feel")
    torch.save(payload, path)
    with pytest.raises(ConfigError, match=r"trained with the hidden properties .*differing: \['temperature'\]"):
        LearnedPlannerAgent(checkpoint=str(path))


def test_a_small_trained_planner_solves_unseen_symbolic_episodes(tmp_path):
    """24 training scenes, 6 epochs: the planner solves most instructions of seed-disjoint scenes, across
    templates (untrained, or after one epoch, it solves few)."""
    PlannerTrainer(scenes=24, epochs=6, validation_scenes=0, batch_size=64).train(_run(tmp_path / "run", seed=1))
    agent = LearnedPlannerAgent(checkpoint=str(tmp_path / "run" / "planner.pt"))
    solved, total, templates = 0, 0, set()
    for index in range(5):
        scene = scene_for(1, index, True)
        for instruction in instructions_for(scene, 1, index, True):
            result = run_symbolic_episode(instruction, scene, agent)
            total += 1
            if result.outcome is Outcome.SUCCESS:
                solved += 1
                templates.add(instruction.template_id)
    assert total >= 25
    assert solved >= 0.8 * total, f"{solved}/{total}"
    assert len(templates) >= 6


def test_a_planner_trained_on_the_physical_family_pushes_balances_and_shakes(tmp_path):
    """trainer.templates names the family: a small planner learns to measure friction, centre of mass and
    contents (push, balance, shake) and solves most physical instructions of seed-disjoint scenes."""
    from muble_plugins.tasks.templates import PHYSICAL_TEMPLATES

    family = tuple(PHYSICAL_TEMPLATES)
    PlannerTrainer(scenes=30, epochs=6, validation_scenes=0, batch_size=64,
                   templates=list(family)).train(_run(tmp_path / "run", seed=1))
    agent = LearnedPlannerAgent(checkpoint=str(tmp_path / "run" / "planner.pt"))
    solved, total, used = 0, 0, set()
    for index in range(6):
        scene = scene_for(1, index, True)
        for instruction in instructions_for(scene, 1, index, True, family):
            result = run_symbolic_episode(instruction, scene, agent)
            total += 1
            solved += result.outcome is Outcome.SUCCESS
            used |= {a.name for a in result.actions}
    assert total >= 15
    assert solved >= 0.8 * total, f"{solved}/{total}"
    assert {"push", "balance", "shake"} <= used
    with pytest.raises(ConfigError, match="trainer.templates"):
        PlannerTrainer(templates=["no_such_template"])
