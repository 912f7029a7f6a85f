"""A command's plan: the protocol split, where its files are, track and mode, resolved once, typed and frozen."""
from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf.errors import ReadonlyConfigError

from muble.app.config import compose
from muble.app.plan import resolve
from muble.core.errors import ConfigError
from muble.core.types import ObservationMode, Track
from muble.dataset.shipped import shipped_split_root


def test_a_protocol_split_resolves_to_its_size_and_shipped_files_leaving_the_config_alone(tmp_path):
    cfg = compose("eval", ["protocol=shopvrb2_v2", "benchmark.split=mini", "benchmark.mode=masks",
                           f"dataset.root={tmp_path}"])
    plan = resolve(cfg, files="read")
    assert (plan.protocol, plan.split, plan.splits, plan.sizes) == ("shopvrb2_v2", "mini", ("mini",), (100,))
    assert plan.track is Track.program and plan.mode is ObservationMode.masks
    assert plan.root == shipped_split_root(cfg, "mini") and plan.root != Path(tmp_path)  # no copy there
    assert plan.config.dataset.root == str(plan.root)
    assert str(cfg.dataset.root) == str(tmp_path)  # the caller's config is as it was
    with pytest.raises(ReadonlyConfigError):
        plan.config.dataset.root = "elsewhere"  # nothing later in the run changes the plan


def test_generation_writes_the_split_into_dataset_root_and_bad_settings_are_named(tmp_path):
    cfg = compose("generate", ["protocol=shopvrb2_v2", "benchmark.split=mini", f"dataset.root={tmp_path}"])
    plan = resolve(cfg, files="write")
    assert plan.root == Path(tmp_path) and list(plan.config.dataset.sizes) == [100]
    with pytest.raises(ConfigError, match="closed_loop.*muble serve does not apply"):
        resolve(compose("run", ["protocol=shopvrb2_v2", "benchmark.split=closed_loop"]), files="serve")
