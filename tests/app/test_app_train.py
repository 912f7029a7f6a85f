"""``muble train``: a registered trainer (built-in or a third party's) runs from the command line with its own
settings, is handed the run's seed, folder and record, and its figures land in ``train.json``; bad settings are
usage errors that leave nothing behind."""
from __future__ import annotations

import json
from dataclasses import dataclass

import pytest

import muble.app.hydra_app as hydra_app
import muble.app.train as train_app
from muble import PluginRecord, Trainer, hookimpl
from muble.app.cli import main as muble_main
from muble.plugins.manager import make_plugin_manager
from muble.plugins.registry import Registry


@dataclass
class CountConfig:
    steps: int = 3


class CountingTrainer(Trainer):
    """Writes one line per step into its checkpoint; resumes from the lines already there."""

    def __init__(self, steps: int = 3) -> None:
        self.steps = steps

    def train(self, run):
        path = run.out_dir / "count.txt"
        done = path.read_text().splitlines() if run.resume and path.exists() else []
        lines = done + [f"{run.seed}:{i}" for i in range(len(done), self.steps)]
        path.write_text("\n".join(lines) + "\n")
        return {"steps": len(lines), "resumed_from": len(done), "seed": run.seed,
                "recorded_steps": run.record["config"]["trainer"]["steps"]}


class CountPlugin:
    """A third party's plugin: the trainer and its config file (``trainer/count.yaml`` in its config folder)."""

    def __init__(self, conf) -> None:
        self.conf = conf

    @hookimpl
    def muble_register_trainers(self):
        return [PluginRecord("count", CountingTrainer, "counts", CountConfig)]

    @hookimpl
    def muble_config_searchpath(self):
        return [f"file://{self.conf}"]


@pytest.fixture
def registry(monkeypatch, clear_hydra, tmp_path):
    conf = tmp_path / "conf"
    (conf / "trainer").mkdir(parents=True)
    (conf / "trainer" / "count.yaml").write_text("defaults:\n  - count_schema\n  - _self_\n")
    registry = Registry(make_plugin_manager(extra_plugins=(CountPlugin(conf),)))
    monkeypatch.setattr(hydra_app, "get_registry", lambda: registry)
    monkeypatch.setattr(train_app, "get_registry", lambda: registry)
    return registry


def test_a_third_party_trainer_runs_with_its_settings_and_its_figures_are_written(registry, tmp_path, capsys):
    out = tmp_path / "run"
    assert muble_main(["train", "trainer=count", "trainer.steps=5", "seed=7", f"train.out_dir={out}"]) == 0
    assert (out / "count.txt").read_text().splitlines() == [f"7:{i}" for i in range(5)]
    summary = json.loads((out / "train.json").read_text())
    assert summary["trainer"] == "count" and summary["seed"] == 7
    assert summary["figures"] == {"steps": 5, "resumed_from": 0, "seed": 7, "recorded_steps": 5}
    assert "numpy" in summary["versions"]
    assert "steps: 5" in capsys.readouterr().out
    # Again into the same folder with more steps: it goes on from what is there.
    assert muble_main(["train", "trainer=count", "trainer.steps=6", "seed=7", f"train.out_dir={out}"]) == 0
    assert json.loads((out / "train.json").read_text())["figures"]["resumed_from"] == 5


def test_an_unknown_trainer_or_setting_is_a_usage_error(registry, tmp_path, capsys):
    out = tmp_path / "run"
    assert muble_main(["train", "trainer=cuont", f"train.out_dir={out}"]) == 2
    err = capsys.readouterr().err
    assert "cuont" in err and "count" in err
    assert muble_main(["train", "trainer=count", "trainer.stpes=2", f"train.out_dir={out}"]) == 2
    assert "stpes" in capsys.readouterr().err
    assert muble_main(["train", "trainer=count", f"train.data_root={tmp_path / 'none'}",
                       f"train.out_dir={out}"]) == 2
    assert "train.data_root" in capsys.readouterr().err
    assert not out.exists()
