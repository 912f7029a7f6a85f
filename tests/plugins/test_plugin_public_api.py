"""The public API a plugin may import (docs/plugins.md, "The public API"): every name the page lists imports, the
example package and the page's own code import nothing else, and the modules that moved keep their old names for
one minor release, with a warning that names the new one."""
from __future__ import annotations

import ast
import importlib
import re
import sys
import warnings
from pathlib import Path

import pytest
from packaging.version import Version

import muble
from muble.core.errors import MubleDeprecationWarning
from muble.plugins import Registry, deprecated, make_plugin_manager
from muble.plugins.manager import REPORTED_ENV

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "plugins.md"
EXAMPLE = ROOT / "docs" / "examples" / "muble-example-plugin" / "muble_example_plugin"


def _section(title: str, level: str = "## ") -> str:
    text = PAGE.read_text()
    start = text.index(f"\n{level}{title}\n")
    end = text.find(f"\n{level}", start + 1)
    return text[start:end if end != -1 else None]


def _rows(section: str) -> list[list[str]]:
    """The cells of the first table of ``section`` (header and rule left out)."""
    rows = []
    for line in section.splitlines():
        if line.startswith("|"):
            rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
        elif rows:
            break
    return rows[2:]


def public_api() -> dict[str, set[str]]:
    """Module -> the names the page lists for it."""
    table = _section("The public API: what a plugin may import").split("\n### ")[0]
    out = {}
    for module, names in _rows(table):
        (name,) = re.fullmatch(r"`([\w.]+)`", module).groups()
        out[name] = set(re.findall(r"`(\w+)`", names))
    return out


def moved() -> dict[str, str]:
    """Old module -> new module, from the page's table of names that moved."""
    section = _section("Names that moved", level="### ")
    return {old.strip("`"): new.strip("`") for old, new in _rows(section)}


MUBLE_PACKAGES = ("muble", "muble_plugins")  # what MuBlE installs: the core and its own plugins


def muble_imports(source: str) -> list[tuple[int, str, str | None]]:
    """(line, module, name) of every use of MuBlE (``MUBLE_PACKAGES``) in ``source``: ``from muble.x import y`` is
    ("muble.x", "y"); ``import muble.x`` followed by ``muble.x.y.z`` is the chain "muble.x.y.z" (name None),
    resolved by ``unlisted``."""
    tree = ast.parse(source)
    aliases: dict[str, str] = {}  # a local name bound to a MuBlE module
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 \
                and (node.module or "").split(".")[0] in MUBLE_PACKAGES:
            found += [(node.lineno, node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                top = a.name.split(".")[0]
                if top in MUBLE_PACKAGES:
                    aliases[a.asname or top] = a.name if a.asname else top
                    if a.asname or a.name != top:
                        found.append((node.lineno, a.name, None))
    parents = {child: parent for parent in ast.walk(tree) for child in ast.iter_child_nodes(parent)}
    for node in ast.walk(tree):
        # The longest attribute chain on a name bound to a MuBlE module: muble.core.types.Pose, muble.Sensor.
        if not isinstance(node, ast.Attribute) or isinstance(parents.get(node), ast.Attribute):
            continue
        chain, base = [], node
        while isinstance(base, ast.Attribute):
            chain.insert(0, base.attr)
            base = base.value
        if isinstance(base, ast.Name) and base.id in aliases:
            found.append((node.lineno, ".".join([aliases[base.id], *chain]), None))
    return sorted(found, key=lambda use: use[0])


def unlisted(uses: list[tuple[int, str, str | None]], api: dict[str, set[str]]) -> list[str]:
    """The uses of MuBlE that the public API does not list."""
    out = []
    for line, module, name in uses:
        if name is not None:
            dotted = f"{module}.{name}"
            if module in api and (name in api[module] or dotted in api):
                continue
            if dotted in api:  # from muble.core import streams: a listed module
                continue
        else:
            dotted = module
            prefix = max((m for m in api if dotted == m or dotted.startswith(m + ".")), key=len, default=None)
            rest = dotted[len(prefix) + 1:].split(".")[0] if prefix else None
            if prefix is not None and (not rest or rest in api[prefix]):
                continue
        out.append(f"line {line}: {dotted}")
    return out


def _code_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


# --- the list is true -----------------------------------------------------------------------------------------
def test_the_page_lists_the_interfaces_a_plugin_implements():
    api = public_api()
    assert {"muble", "muble.plugins", "muble.core.interfaces", "muble.core.types", "muble.core.errors",
            "muble.core.environment", "muble.core.streams", "muble.programs.program"} <= api.keys()
    assert {"Agent", "Task", "PrimitiveAction", "Sensor", "Disturbance", "Trainer"} <= api["muble.core.interfaces"]


def test_every_listed_name_imports_and_none_is_an_alias():
    missing = []
    with warnings.catch_warnings():
        warnings.simplefilter("error", MubleDeprecationWarning)  # a listed module is never a deprecated alias
        for module, names in public_api().items():
            assert module not in deprecated.MOVED, module
            imported = importlib.import_module(module)
            assert imported.__name__ == module, f"{module} is {imported.__name__}"
            missing += [f"{module}.{n}" for n in sorted(names) if not hasattr(imported, n)]
    assert not missing, f"docs/plugins.md lists names that do not exist: {missing}"


def test_the_muble_row_is_exactly_the_package_s_exports():
    assert public_api()["muble"] == set(muble.__all__)


def test_the_example_package_imports_only_the_public_api():
    api = public_api()
    files = sorted(EXAMPLE.glob("*.py"))
    assert {f.name for f in files} >= {"__init__.py", "agent.py", "touch.py", "nudge.py"}
    found = {f.name: unlisted(muble_imports(f.read_text()), api) for f in files}
    assert not any(found.values()), found
    # It uses MuBlE in both spellings, so the check reads something: muble.PluginRecord, from muble import Param.
    uses = {(m, n) for f in files for _, m, n in muble_imports(f.read_text())}
    assert ("muble.PluginRecord", None) in uses and ("muble", "Param") in uses


def test_the_page_s_code_imports_only_the_public_api():
    blocks = _code_blocks(PAGE)
    assert len(blocks) >= 3
    found = [problem for block in blocks for problem in unlisted(muble_imports(block), public_api())]
    assert not found, found


def test_the_check_finds_what_the_list_does_not_hold():
    source = ("import muble\nimport muble.core.streams as streams\nfrom muble import Agent, TabletopEnv\n"
              "from muble.sim.env import TabletopEnv as Env\nfrom muble.core.observation import MEASURED_EXTRA\n"
              "from muble.core import streams as s2\n"
              "x = muble.Sensor\ny = muble.core.observation.MEASURED_EXTRA['weight']\nz = streams.stream\n"
              "w = streams.PROPERTY_STREAMS\nv = muble.get_registry().create('agent', 'oracle')\n")
    assert unlisted(muble_imports(source), public_api()) == [
        "line 3: muble.TabletopEnv", "line 4: muble.sim.env.TabletopEnv",
        "line 5: muble.core.observation.MEASURED_EXTRA", "line 8: muble.core.observation.MEASURED_EXTRA",
        "line 10: muble.core.streams.PROPERTY_STREAMS"]


def test_the_check_reads_muble_s_own_plugins_too():
    source = ("from muble_plugins.tasks import template_tasks\n"
              "from muble_plugins.tasks.tasks import template_file_tasks\nimport muble_plugins.common.success\n"
              "import muble_plugins.tasks\nx = muble_plugins.tasks.template_tasks\n")
    assert unlisted(muble_imports(source), public_api()) == [
        "line 2: muble_plugins.tasks.tasks.template_file_tasks", "line 3: muble_plugins.common.success"]


# --- the names that moved -------------------------------------------------------------------------------------
def test_the_page_lists_exactly_the_aliases():
    assert moved() == deprecated.MOVED
    assert {"muble.core.descriptions", "muble.core.program", "muble.core.scene_io"} <= moved().keys()


@pytest.mark.parametrize("old", sorted(deprecated.MOVED))
def test_an_old_name_is_the_moved_module_and_warns_with_the_new_name(old, monkeypatch):
    new = importlib.import_module(deprecated.MOVED[old])
    monkeypatch.delitem(sys.modules, old, raising=False)  # imported by an earlier test: import it afresh
    with pytest.warns(DeprecationWarning, match=re.escape(f"{old} moved to {new.__name__}")) as caught:
        alias = importlib.import_module(old)
    assert alias is new
    assert all(issubclass(w.category, MubleDeprecationWarning) for w in caught)


def test_the_warning_points_at_the_import_and_a_name_never_there_is_still_an_error(monkeypatch):
    monkeypatch.delitem(sys.modules, "muble.core.program", raising=False)
    with pytest.warns(MubleDeprecationWarning) as caught:
        from muble.core.program import execute  # noqa: F401
    assert caught[0].filename == __file__
    with pytest.raises(ModuleNotFoundError, match="muble.core.teleport"):
        importlib.import_module("muble.core.teleport")


def test_the_aliases_go_in_the_release_they_name():
    assert Version(muble.__version__) < Version(deprecated.REMOVED_IN), \
        f"MuBlE {muble.__version__}: remove muble/plugins/deprecated.py's aliases, as docs/plugins.md promises"


OLD_STYLE = '''
"""A plugin package written against the previous release's documented imports."""
import muble
from muble.core.descriptions import SceneIndex, describe
from muble.core.program import execute
from muble.core.scene_io import load_scene

SEEN = (SceneIndex, describe, execute, load_scene)


class Idle(muble.Agent):
    def act(self, instruction, observation):
        return None


@muble.hookimpl
def muble_register_agents():
    return [muble.PluginRecord("idle_old", Idle, "stops at once")]
'''


def test_a_package_written_against_the_old_imports_still_loads_and_is_named(fake_distribution, monkeypatch,
                                                                             caplog):
    for old in ("muble.core.descriptions", "muble.core.program", "muble.core.scene_io"):
        monkeypatch.delitem(sys.modules, old, raising=False)
    monkeypatch.setenv(REPORTED_ENV, "")
    fake_distribution("acme-old", {"acme_old": "acme_old"}, {"acme_old": OLD_STYLE})
    with caplog.at_level("WARNING", logger="muble.plugins.manager"):
        registry = Registry(make_plugin_manager())
    assert registry.broken == [] and registry.get("agent", "idle_old").distribution == "acme-old"
    from muble.programs.program import execute

    assert sys.modules["acme_old"].SEEN[2] is execute
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3, lines
    for line, new in zip(lines, ("muble.programs.descriptions", "muble.programs.program", "muble.io.scene_io")):
        assert line.startswith("plugin package 'acme-old' (entry point 'acme_old'") and f"import {new} instead" in line


def test_the_api_reference_documents_every_module_of_the_list():
    from tests.support.scripts import load_script

    reference = load_script("scripts/api_reference.py").API_MODULES
    assert set(public_api()) <= set(reference), sorted(set(public_api()) - set(reference))
