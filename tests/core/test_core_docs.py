"""Meta-tests: every hook has a test and a docs entry; every interface has a docs entry."""
from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from muble.core.interfaces import INTERFACES
from muble.plugins import hookspecs

ROOT = Path(__file__).resolve().parents[2]
HOOKS = sorted(name for name, f in inspect.getmembers(hookspecs, inspect.isfunction) if name.startswith("muble_"))


def _text(folder: str) -> str:
    return "\n".join(p.read_text() for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".md"))


def test_hooks_exist():
    assert len(HOOKS) >= 8


@pytest.mark.parametrize("hook", HOOKS)
def test_hook_has_docs_entry(hook):
    assert hook in (ROOT / "docs" / "plugins.md").read_text(), f"document {hook} in docs/plugins.md"


@pytest.mark.parametrize("hook", HOOKS)
def test_hook_has_a_test(hook):
    from muble.plugins.records import KINDS

    tests = _text("tests")
    own = Path(__file__).read_text()
    # The parametrised hook test covers every registration hook through KINDS; others must be named in a test.
    covered = hook in KINDS.values() and "test_every_registration_hook_registers_its_kind" in tests
    assert covered or hook in tests.replace(own, ""), f"write a test that exercises {hook}"


@pytest.mark.parametrize("interface", sorted(INTERFACES))
def test_interface_has_docs_entry(interface):
    assert INTERFACES[interface].__name__ in (ROOT / "docs" / "concepts.md").read_text()


def test_every_config_option_is_documented():
    reference = (ROOT / "docs" / "configs.md").read_text()
    for group in sorted(p for p in (ROOT / "muble_conf").iterdir() if p.is_dir() and not p.name.startswith("_")):
        assert f"`{group.name}`" in reference, f"document config group {group.name} in docs/configs.md"
        for option in group.glob("*.yaml"):
            assert f"`{option.stem}`" in reference, f"document {group.name}={option.stem} in docs/configs.md"
