"""The public API reference is generated from the docstrings (scripts/api_reference.py, pdoc): it builds, it shows
the interfaces a plugin implements, and no public name lacks a docstring, so it cannot fall behind the code."""
from __future__ import annotations

import pytest

from tests.support.scripts import load_script

pytest.importorskip("pdoc")


def _script():
    return load_script("scripts/api_reference.py")


def test_every_public_name_has_a_docstring():
    assert _script().undocumented() == []


def test_a_public_name_without_a_docstring_is_found(tmp_path, monkeypatch):
    (tmp_path / "half_documented.py").write_text('"""A module."""\n\n\ndef told():\n    """Says."""\n\n\n'
                                                 'def untold():\n    pass\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _script().undocumented(("half_documented",)) == ["half_documented.untold"]


def test_the_reference_builds_with_the_interfaces_and_the_core_modules(tmp_path):
    index = _script().build(tmp_path / "api")
    assert index.is_file()
    page = (tmp_path / "api" / "muble.html").read_text()
    for name in ("Trainer", "TrainingRun", "PrimitiveAction", "symbolic_effect", "Agent", "SceneGraph"):
        assert f'id="{name}' in page or f'id="PrimitiveAction.{name}' in page, name
    assert (tmp_path / "api" / "muble" / "programs" / "program.html").is_file()
