"""docs/planning.md's table of the numbers that govern grasping, placing and retreating says what the code holds:
every row names a constant of a built-in primitive module, with its value."""
from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import numpy as np

DOC = Path(__file__).resolve().parents[2] / "docs" / "planning.md"
ROW = re.compile(r"^\| `(\w+)\.(\w+)` \| ([^|]+) \|")


def _rows() -> list[tuple[str, str, str]]:
    text = DOC.read_text()
    section = text.split("### The numbers that govern grasping, placing and retreating", 1)[1].split("\n## ", 1)[0]
    return [m.groups() for line in section.splitlines() if (m := ROW.match(line))]


def test_the_table_names_each_constant_with_the_value_the_code_holds():
    rows = _rows()
    assert len(rows) >= 15  # the table was found and read
    for module, name, value in rows:
        actual = getattr(importlib.import_module(f"muble_plugins.primitives.{module}"), name)
        np.testing.assert_allclose(np.asarray(actual, float), np.asarray(ast.literal_eval(value.strip()), float),
                                   err_msg=f"{module}.{name}")


def test_no_pose_tolerance_or_settling_time_is_written_as_a_bare_number():
    folder = Path(importlib.import_module("muble_plugins.primitives").__file__).parent
    # On one line: a pose goal ending in two numbers, a pose goal of a named pose and a number, a hold of a number.
    bare = re.compile(r"PoseGoal\(.*\),\s*0\.\d+\s*,\s*0\.\d+\)|PoseGoal\(\w+, 0\.\d+|\.hold\(0\.\d+")
    found = [f"{p.name}: {m.group(0)}" for p in sorted(folder.glob("*.py")) if p.name != "tolerances.py"
             for m in bare.finditer(p.read_text())]
    assert not found, found
