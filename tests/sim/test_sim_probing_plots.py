"""scripts/probing_plots.py draws the wrist sensor during ``push``, ``balance`` and ``shake`` from real runs: its
recording leaves the readings as they are, and its series give the primitives' own readings back."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "probing_plots.py"


@pytest.fixture(scope="module")
def plots():
    spec = importlib.util.spec_from_file_location("probing_plots", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def test_sim_the_recorded_push_is_the_unrecorded_one_and_its_series_read_its_friction(plots):
    run = plots.measure("push", plots.PUSH_OBJECT, friction_coefficient=plots.PUSH_FRICTION)
    plain = plots.measure("push", plots.PUSH_OBJECT, record=False, friction_coefficient=plots.PUSH_FRICTION)
    assert run.result.measurement == plain.result.measurement  # bit for bit: recording only reads
    series = plots.push_series(run)
    assert series["friction"] == pytest.approx(run.result.measurement, rel=1e-12)
    assert int(series["steady"].sum()) == run.result.info["samples"]


def test_sim_the_recorded_balance_gives_the_centre_of_mass_it_read(plots):
    offset = np.array(plots.BALANCE_OFFSET)
    run = plots.measure("balance", plots.BALANCE_OBJECT, com_offset=offset)
    assert run.result.measurement == plots.measure("balance", plots.BALANCE_OBJECT, record=False,
                                                   com_offset=offset).result.measurement
    series = plots.balance_series(run)
    read = 1000.0 * series["offset"][series["window"]].mean(axis=0)
    np.testing.assert_allclose(read, run.result.measurement, atol=0.01)  # the reading is rounded to 0.01 mm


def test_sim_the_recorded_shake_has_the_peak_the_primitive_read(plots):
    grams = plots.SHAKE_CONTENTS_G / 1000.0
    loose = plots.measure("shake", plots.SHAKE_OBJECT, contents_mass=grams)
    plain = plots.measure("shake", plots.SHAKE_OBJECT, record=False, contents_mass=grams)
    assert loose.result.info["peak_force"] == plain.result.info["peak_force"]
    assert plots.shake_series(loose)["peak"] == pytest.approx(loose.result.info["peak_force"], rel=1e-9)
    assert loose.result.measurement is True
