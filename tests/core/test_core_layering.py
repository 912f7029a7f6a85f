"""The layering of ``muble`` (see docs/architecture.md): imports run one way, there are no import circles (among
the modules of ``muble`` and the built-in plugins together), no plugin imports another's private names, and the
core names no built-in plugin: neither as a name it asks the registry for nor as a function or method it defines
(the environment has no ``weigh``: the primitive takes its reading through the environment's sensing API).

Every ``import`` is read from the whole source with ``ast`` (those inside functions and under ``if TYPE_CHECKING:``
too), so a lazy import cannot hide a wrong direction or close a circle at run time, and an import for annotations
only closes a circle as well: the types both sides need belong in the lower module, or in a leaf module of their own. To allow something, add one line to a table below, with the
reason; a line no longer needed fails ``test_the_exceptions_are_still_needed``.
"""
from __future__ import annotations

import ast
import functools
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# Package -> layer. A module may import its own layer and the ones below it, never one above.
LAYERS = {
    "muble.app": 8, "muble.gym": 8,  # entry points: the CLI, the Gymnasium environments
    "muble.dataset": 7, "muble.evaluation": 7, "muble.remote": 7,
    "muble.episode": 6,
    "muble.generation": 5,
    "muble.sim": 4,
    "muble.plugins": 3, "muble": 3, "muble.quiet": 3,  # the plugin machinery, the public API, its log filters
    "muble.programs": 2, "muble.io": 2,  # task programs and object descriptions; the files MuBlE reads and writes
    "muble.stage": 1,  # the tabletop: the stages, the table's parts, free places, objects at rest
    "muble.core": 0,  # the data model and the plugin interfaces
}
# The most modules ``muble/core`` holds (``__init__.py`` counted): the data model and the plugin interfaces only.
CORE_MODULES_MAX = 15

# The built-in plugin packages (the ``muble`` entry points), and the one package beside them that every plugin may
# import: it registers nothing and imports no plugin.
PLUGIN_PACKAGES = sorted(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]["muble"]
                         .values())
SHARED_PACKAGE = "muble_plugins.common"

# Further rules, one line each: (importing package, imported package it may not import, why).
FORBIDDEN = [
    ("muble", "muble_plugins", "the core knows plugins only through the registry, by name"),
    ("muble_plugins", "muble.app", "plugins use the public API, not the command line's internals"),
    ("muble_plugins", "muble.dataset", "plugins do not write datasets; the core calls them"),
    ("muble_plugins", "muble.evaluation", "plugins do not run evaluations; the core calls them"),
    ("muble_plugins", "muble.generation", "plugins do not generate scenes; the core calls them"),
    ("muble_plugins", "muble.sim", "plugins use the environment they are handed (muble.core.environment), not "
                               "the simulation's modules"),
    *[(SHARED_PACKAGE, plugin, "the shared package is what the plugins import; it imports none of them")
      for plugin in PLUGIN_PACKAGES],
]

# Imports allowed against the rules (a layer, a plugin rule, a private name or an import circle): (file, imported
# module) -> why it must stay. None is needed today.
EXCEPTIONS: dict[tuple[str, str], str] = {}

# Plugin names that ``muble/`` may write as plugin names: (file, name) -> why.
_ORIGINAL = ("the original MuBlE sequence files name these built-in primitives differently; the mapping is part of "
             "that file format (muble.io.action_names), and any other primitive keeps its registry name")
NAME_EXCEPTIONS: dict[tuple[str, str], str] = {
    **{("muble/io/action_names.py", n): _ORIGINAL for n in ("approach", "close_gripper", "lift", "lower",
                                                            "open_gripper")},
}

# Functions and methods of ``muble/`` named like a built-in primitive: (file, name) -> why. A measuring primitive's
# procedure lives in the primitive, written against the environment's generic sensing members, so that a package
# can add one; the environment may not know it.
_ACTUATOR = ("the finger actuators' command, which every primitive that moves the fingers sends; the primitive of "
             "that name also waits for the fingers and checks the grasp")
DEFINITION_EXCEPTIONS: dict[tuple[str, str], str] = {
    (f, n): _ACTUATOR for f in ("muble/core/environment.py", "muble/sim/env.py") for n in ("open_gripper",
                                                                                         "close_gripper")}


def _module(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _files(folder: str) -> list[Path]:
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "build" not in p.relative_to(ROOT).parts)


@functools.lru_cache(maxsize=None)
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


def _from_base(path: Path, node: ast.ImportFrom) -> str:
    """The module an ``ImportFrom`` in the file names, a relative one resolved."""
    package = _module(path) if path.name == "__init__.py" else _module(path).rpartition(".")[0]
    base = node.module or ""
    if node.level:
        base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
    return base


def _imports(path: Path, top_level_only: bool = False) -> list[tuple[int, str]]:
    """(line, imported module) of every import in the file (inside functions and ``if TYPE_CHECKING:`` blocks too,
    unless ``top_level_only``); relative imports resolved."""
    tree = _tree(path)
    nodes = tree.body if top_level_only else ast.walk(tree)
    found = []
    for node in nodes:
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _from_base(path, node)
            # ``from muble.core import scene`` imports the module muble.core.scene; ``from muble import X`` muble
            found += [(node.lineno, f"{base}.{a.name}" if f"{base}.{a.name}" in _modules() else base)
                      for a in node.names]
    return found


def _imported_names(path: Path) -> list[tuple[int, str]]:
    """(line, dotted name) of everything the file imports, annotations' imports included: a module
    (``import a.b``) or a name of one (``from a.b import c``: ``a.b.c``); relative imports resolved."""
    found = []
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            found += [(node.lineno, f"{_from_base(path, node)}.{a.name}") for a in node.names if a.name != "*"]
    return found


def _modules() -> set[str]:
    return _modules_under(ROOT)


@functools.lru_cache(maxsize=None)
def _modules_under(root: Path) -> set[str]:
    return {_module(p) for folder in ("muble", "muble_plugins") for p in _files(folder) if (root / folder).is_dir()}


def _layer(module: str) -> str | None:
    """The package of LAYERS that ``module`` belongs to (the longest match), or None outside ``muble``."""
    matches = [p for p in LAYERS if module == p or module.startswith(p + ".")]
    return max(matches, key=len) if matches else None


def _under(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def layer_violations(files: list[Path]) -> list[str]:
    out = []
    for path in files:
        rel, importer = str(path.relative_to(ROOT)), _module(path)
        mine = _layer(importer)
        for line, imported in _imports(path):
            theirs = _layer(imported)
            if mine is None or theirs is None or (rel, imported) in EXCEPTIONS:
                continue
            if LAYERS[theirs] > LAYERS[mine]:
                out.append(f"{rel}:{line}: {importer} ({mine}, layer {LAYERS[mine]}) imports {imported} "
                           f"({theirs}, layer {LAYERS[theirs]}): imports run from higher layers to lower ones")
    return out


def rule_violations(files: list[Path]) -> list[str]:
    out = []
    for path in files:
        rel, importer = str(path.relative_to(ROOT)), _module(path)
        for line, imported in _imports(path):
            for who, what, why in FORBIDDEN:
                if _under(importer, who) and _under(imported, what) and (rel, imported) not in EXCEPTIONS:
                    out.append(f"{rel}:{line}: {importer} imports {imported}: {why}")
    return out


def _plugin_package(module: str) -> str | None:
    """``muble_plugins.X`` for a module of the built-in plugin package (or the shared package) X, else None."""
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "muble_plugins" and len(parts) > 1 else None


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def private_imports(files: list[Path]) -> list[str]:
    """Imports by a module of one package of ``muble_plugins`` of a private name of another: a name starting with
    ``_``, or anything from a module whose name does."""
    out = []
    for path in files:
        rel, importer = str(path.relative_to(ROOT)), _module(path)
        mine = _plugin_package(importer)
        for line, name in _imported_names(path):
            theirs = _plugin_package(name)
            if mine is None or theirs is None or theirs == mine:
                continue
            private = [p for p in name[len(theirs) + 1:].split(".") if _private(p)]
            module = name.rpartition(".")[0] if name not in _modules() else name
            if private and (rel, module) not in EXCEPTIONS:
                out.append(f"{rel}:{line}: {importer} imports {name}, private to {theirs}: make it public there "
                           f"or move it to {SHARED_PACKAGE}")
    return out


def cycles(files: list[Path]) -> list[list[str]]:
    """Import circles among the files' modules, counting every import: at module level, inside functions (a lazy
    import closes a circle at run time just the same) and under ``if TYPE_CHECKING:`` (two modules that need each
    other's names even for annotations only are one concern split in two, and a type checker follows the circle)."""
    modules = {_module(p): p for p in files}
    graph = {}
    for module, path in modules.items():
        # A package's __init__ runs before its modules in any case; the edges are the modules named.
        rel = str(path.relative_to(ROOT))
        targets = {imported for _, imported in _imports(path)
                   if (rel, imported) not in EXCEPTIONS} & modules.keys()
        graph[module] = sorted(targets - {module})
    found, state = [], {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in graph[node]:
            if state.get(nxt) == 1:
                found.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [])
    return found


def builtin_plugin_names() -> set[str]:
    """Every name the built-in plugins (``muble_plugins``) register, of every kind."""
    from muble.plugins.registry import get_registry

    return {p.record.name for p in get_registry().all()
            if getattr(p.record.factory, "__module__", "").startswith("muble_plugins")}


def builtin_primitive_names() -> set[str]:
    """The names of the primitives the built-in plugins register."""
    from muble.plugins.registry import get_registry

    return {name for name in get_registry().names("primitive")
            if getattr(get_registry().get("primitive", name).record.factory, "__module__", "").startswith(
                "muble_plugins")}


def primitive_definitions(files: list[Path], names: set[str]) -> list[str]:
    """Functions, methods and class attributes of the files named like one of ``names`` (built-in primitives),
    less ``DEFINITION_EXCEPTIONS``."""
    out = []
    for path in files:
        rel = str(path.relative_to(ROOT))
        defined = []
        for node in ast.walk(_tree(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                defined.append((node.lineno, node.name))
            elif isinstance(node, ast.ClassDef):
                defined += [(n.lineno, t.id) for n in node.body if isinstance(n, (ast.Assign, ast.AnnAssign))
                            for t in (n.targets if isinstance(n, ast.Assign) else [n.target])
                            if isinstance(t, ast.Name)]
        out += [f"{rel}:{line}: {name!r} is a built-in primitive: its procedure belongs in the primitive, written "
                "against the environment's sensing API (docs/plugins.md)"
                for line, name in sorted(defined) if name in names and (rel, name) not in DEFINITION_EXCEPTIONS]
    return out


KINDS = ("renderer", "planner", "primitive", "sensor", "task", "object_set", "objects", "agent")


def _kindlike(name: str | None) -> bool:
    return bool(name) and any(name == k or name.endswith("_" + k) or name.rstrip("s") == k for k in KINDS)


def _strings(node: ast.AST) -> list[ast.Constant]:
    return [n for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def plugin_name_uses(path: Path, names: set[str]) -> list[tuple[int, str]]:
    """String literals of ``names`` used as plugin names: an argument of ``.create``/``.get``, compared with
    something's ``name``, the default of a parameter or field named after a plugin kind, or a constant that holds
    only plugin names (``MOVE, LIFT = "move", "lift"``, or a mapping keyed by them)."""
    found = []
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("create", "get") \
                and len(node.args) >= 2 and isinstance(node.args[0], ast.Constant) and node.args[0].value in KINDS:
            found += [(c.lineno, c.value) for c in _strings(node.args[1]) if c.value in names]
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "add_argument":
            # A command-line option named after a plugin kind whose default is a built-in plugin.
            options = [c.value.lstrip("-").replace("-", "_") for c in node.args if isinstance(c, ast.Constant)
                       and isinstance(c.value, str)]
            found += [(k.value.lineno, k.value.value) for k in node.keywords if k.arg == "default"
                      and any(_kindlike(o) for o in options) and isinstance(k.value, ast.Constant)
                      and k.value.value in names]
        elif isinstance(node, ast.Call):
            # A keyword argument named after a plugin kind: ``make(renderer="mujoco")``.
            found += [(k.value.lineno, k.value.value) for k in node.keywords if _kindlike(k.arg)
                      and isinstance(k.value, ast.Constant) and k.value.value in names]
        elif isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(isinstance(s, ast.Attribute) and s.attr == "name" for s in sides):
                found += [(c.lineno, c.value) for s in sides for c in _strings(s) if c.value in names]
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args.posonlyargs + node.args.args
            pairs = list(zip(args[len(args) - len(node.args.defaults):], node.args.defaults))
            pairs += [(a, d) for a, d in zip(node.args.kwonlyargs, node.args.kw_defaults) if d is not None]
            found += [(d.lineno, d.value) for a, d in pairs if _kindlike(a.arg)
                      and isinstance(d, ast.Constant) and d.value in names]
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
            if _kindlike(node.target.id):
                found += [(c.lineno, c.value) for c in _strings(node.value) if c.value in names]
        elif isinstance(node, (ast.Tuple, ast.List, ast.Set, ast.Dict)):
            values = node.keys if isinstance(node, ast.Dict) else node.elts
            if len(values) > 1 and all(isinstance(v, ast.Constant) and v.value in names for v in values):
                found += [(v.lineno, v.value) for v in values]
    return found


def name_violations(files: list[Path], names: set[str]) -> list[str]:
    out = []
    for path in files:
        rel = str(path.relative_to(ROOT))
        out += [f"{rel}:{line}: the built-in plugin name {name!r} (the core knows plugins only through the "
                f"registry, by names from the config)" for line, name in plugin_name_uses(path, names)
                if (rel, name) not in NAME_EXCEPTIONS]
    return out


# --- the rules hold -------------------------------------------------------------------------------------------
def test_imports_run_from_higher_layers_to_lower_ones():
    found = layer_violations(_files("muble"))
    assert not found, "\n".join(found)


def test_plugins_keep_to_their_rules():
    found = rule_violations(_files("muble_plugins"))
    assert not found, "\n".join(found)


def test_the_core_imports_no_plugin():
    found = rule_violations(_files("muble"))
    assert not found, "\n".join(found)


def test_no_plugin_imports_a_private_name_of_another():
    found = private_imports(_files("muble_plugins"))
    assert not found, "\n".join(found)


def test_no_import_circles_among_the_modules_of_muble_and_the_plugins_not_even_for_annotations():
    files = _files("muble") + _files("muble_plugins")
    assert any(_under(_module(p), "muble_plugins.objects") for p in files)  # both trees are read
    found = cycles(files)
    assert not found, "\n".join(" -> ".join(c) for c in found)


def test_every_package_of_muble_plugins_is_a_plugin_or_the_shared_one():
    packages = {_module(p) for p in (ROOT / "muble_plugins").glob("*/__init__.py")}
    assert SHARED_PACKAGE in packages and SHARED_PACKAGE not in PLUGIN_PACKAGES
    assert packages == set(PLUGIN_PACKAGES) | {SHARED_PACKAGE}, \
        f"register these in pyproject.toml's muble entry points: " \
        f"{sorted(packages - set(PLUGIN_PACKAGES) - {SHARED_PACKAGE})}"


def test_the_core_names_no_builtin_plugin():
    names = builtin_plugin_names()
    assert {"mujoco", "weigh", "shopvrb2", "oracle"} <= names  # the names are read from the registry
    found = name_violations(_files("muble"), names)
    assert not found, "\n".join(found)


def test_the_core_defines_nothing_named_after_a_builtin_primitive():
    names = builtin_primitive_names()
    assert {"weigh", "squeeze", "push", "balance", "shake", "open_gripper"} <= names  # read from the registry
    found = primitive_definitions(_files("muble"), names)
    assert not found, "\n".join(found)
    # Each exception still excuses a definition.
    for rel, name in DEFINITION_EXCEPTIONS:
        assert any(isinstance(n, ast.FunctionDef) and n.name == name for n in ast.walk(_tree(ROOT / rel))), \
            f"remove ({rel!r}, {name!r}) from DEFINITION_EXCEPTIONS: nothing there is named so"


def test_the_environment_has_no_member_named_after_a_builtin_primitive():
    """The plugins' environment (the core protocol) and its implementation, members inherited or assigned
    included: a reading that comes back as ``Environment.weigh`` fails here."""
    from muble.core.environment import Environment
    from muble.sim.env import TabletopEnv

    allowed = {name for _, name in DEFINITION_EXCEPTIONS}
    for cls in (Environment, TabletopEnv):
        found = sorted((set(dir(cls)) & builtin_primitive_names()) - allowed)
        assert not found, f"{cls.__module__}.{cls.__qualname__} has {found}: take the reading in the primitive"


def test_every_package_of_muble_has_a_layer():
    packages = {_module(p) for p in (ROOT / "muble").glob("*/__init__.py")} | {
        _module(p) for p in (ROOT / "muble").glob("*.py") if p.name != "__init__.py"}
    assert packages <= LAYERS.keys(), f"give these a layer in LAYERS: {sorted(packages - LAYERS.keys())}"


def test_the_core_holds_the_data_model_and_the_interfaces_only():
    modules = sorted(p.name for p in (ROOT / "muble" / "core").glob("*.py"))
    assert {"__init__.py", "interfaces.py", "scene.py", "types.py"} <= set(modules)
    assert len(modules) <= CORE_MODULES_MAX, \
        f"muble/core holds {len(modules)} modules (at most {CORE_MODULES_MAX}): move what is not the data model " \
        f"or a plugin interface to the package of its concern (muble.io, muble.programs, muble.stage ...): {modules}"


def test_plugins_may_import_the_public_packages():
    # What plugins build on: the data model and interfaces, the tabletop, the files, task programs.
    public = ("muble.core", "muble.stage", "muble.io", "muble.programs")
    assert not [(who, what) for who, what, _ in FORBIDDEN for p in public if who == "muble_plugins" and _under(p, what)]
    assert all(LAYERS[p] < LAYERS["muble.sim"] for p in public)


def findings(files: list[Path]) -> list:
    """Everything the import checks report for ``files`` (layers, plugin rules, private names, circles)."""
    mine = [p for p in files if _under(_module(p), "muble")]
    return layer_violations(mine) + rule_violations(files) + private_imports(files) + cycles(files)


def unneeded_exceptions(files: list[Path]) -> list[str]:
    """Lines of ``EXCEPTIONS`` that excuse nothing: the import is gone, or the checks find nothing without it."""
    imports = {(str(p.relative_to(ROOT)), m) for p in files for _, m in _imports(p)}
    out = []
    for key in list(EXCEPTIONS):
        if key not in imports:
            out.append(f"{key}: the import is gone")
            continue
        allowed = dict(EXCEPTIONS)
        try:
            globals()["EXCEPTIONS"] = {k: v for k, v in allowed.items() if k != key}
            without = findings(files)
        finally:
            globals()["EXCEPTIONS"] = allowed
        if without == findings(files):
            out.append(f"{key}: breaks no rule")
    return out


def test_the_exceptions_are_still_needed():
    stale = unneeded_exceptions(_files("muble") + _files("muble_plugins"))
    assert not stale, f"remove these from EXCEPTIONS: {stale}"


# --- the checks catch what they should ------------------------------------------------------------------------
@pytest.fixture
def tree(tmp_path, monkeypatch):
    """A scratch copy of the layout: files written under it are scanned as ``muble/...`` and ``muble_plugins/...``."""
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    _tree.cache_clear()
    _modules_under.cache_clear()

    def write(rel: str, text: str) -> Path:
        path = tmp_path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        return path

    yield write
    _tree.cache_clear()
    _modules_under.cache_clear()


def test_an_upward_import_inside_a_function_is_found(tree):
    path = tree("muble/sim/bad.py", "def f():\n    from muble.app.run import job\n")
    assert layer_violations([path]) == [
        "muble/sim/bad.py:2: muble.sim.bad (muble.sim, layer 4) imports muble.app.run (muble.app, layer 8): "
        "imports run from higher layers to lower ones"]
    assert layer_violations([tree("muble/app/ok.py", "from muble.sim import env\n")]) == []
    # The core is stated without the tabletop: the stage imports the core, never the other way.
    assert layer_violations([tree("muble/core/bad.py", "from muble.stage.table import STAGES\n")]) == [
        "muble/core/bad.py:1: muble.core.bad (muble.core, layer 0) imports muble.stage.table (muble.stage, layer 1): "
        "imports run from higher layers to lower ones"]


def test_a_plugin_importing_the_app_is_found(tree):
    path = tree("muble_plugins/renderers/x.py", "from muble.app.render import contact_sheet\n")
    assert rule_violations([path]) == ["muble_plugins/renderers/x.py:1: muble_plugins.renderers.x imports "
                                       "muble.app.render: plugins use the public API, not the command line's "
                                       "internals"]


def test_an_import_circle_is_found(tree):
    a = tree("muble/core/a.py", "from muble.core import b\n")
    b = tree("muble/core/b.py", "import muble.core.a\n")
    lazy = tree("muble/core/c.py", "def f():\n    import muble.core.a\n")
    assert cycles([a, b, lazy]) == [["muble.core.a", "muble.core.b", "muble.core.a"]]


def test_an_import_circle_closed_by_a_lazy_import_is_found(tree):
    # As objects/build_cache.py and catalogue.py once were: one imports the other, which imports it back in a
    # function.
    cache = tree("muble_plugins/objects/cache.py", "def key():\n    from muble_plugins.objects.sets import VERSION\n")
    sets = tree("muble_plugins/objects/sets.py", "from muble_plugins.objects.cache import key\nVERSION = 7\n")
    hints = tree("muble_plugins/objects/hints.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                                   "    from muble_plugins.objects.sets import VERSION\n")
    uses = tree("muble_plugins/objects/uses.py", "from muble_plugins.objects.hints import x\n")
    sets_too = tree("muble_plugins/objects/more.py", "import muble_plugins.objects.uses\n")
    assert cycles([cache, sets, hints, uses, sets_too]) == [
        ["muble_plugins.objects.cache", "muble_plugins.objects.sets", "muble_plugins.objects.cache"]]


def test_an_import_circle_for_annotations_only_is_found(tree):
    # As core/environment.py and interfaces.py were: each imports the other's names under ``if TYPE_CHECKING:``
    # (``typing.TYPE_CHECKING`` too), one of them in a function's annotations' block; and as objects/heldout.py was,
    # importing for its hints the catalogue that imports it at run time.
    env = tree("muble/core/env.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                    "    from muble.core.faces import Planner\nclass Env: ...\n")
    faces = tree("muble/core/faces.py", "import typing\nclass Planner: ...\ndef f():\n    if typing.TYPE_CHECKING:\n"
                                        "        from muble.core.env import Env\n")
    held = tree("muble_plugins/objects/held.py", "from __future__ import annotations\nfrom typing import "
                                                 "TYPE_CHECKING\nif TYPE_CHECKING:\n    from "
                                                 "muble_plugins.objects.cat import Category\n")
    cat = tree("muble_plugins/objects/cat.py", "from muble_plugins.objects.held import sampled\n")
    assert cycles([env, faces, held, cat]) == [
        ["muble.core.env", "muble.core.faces", "muble.core.env"],
        ["muble_plugins.objects.cat", "muble_plugins.objects.held", "muble_plugins.objects.cat"]]
    # With the shared types in a leaf module that both import, no circle is left.
    leaf = tree("muble_plugins/objects/kinds.py", "class Category: ...\n")
    held = tree("muble_plugins/objects/held.py", "from muble_plugins.objects.kinds import Category\n")
    _tree.cache_clear()
    assert cycles([held, cat, leaf]) == []


def test_a_circle_through_two_plugins_and_the_core_and_private_names_across_plugins_are_found(tree):
    # A task module imports the oracle, whose module imports the task module back inside a function; the core
    # imports that task module, which imports the core module back.
    plan = tree("muble_plugins/tasks/plan.py", "from muble_plugins.agents.oracle import Oracle\n"
                                               "from muble.core.names import NAMES\n")
    oracle = tree("muble_plugins/agents/oracle.py", "class Oracle:\n    def act(self):\n"
                                                    "        from muble_plugins.tasks import plan\n")
    names = tree("muble/core/names.py", "NAMES = ()\ndef plan():\n    import muble_plugins.tasks.plan\n")
    # Private names across plugins: another plugin's private helper, a name of another plugin's private module (by
    # a relative import too); a package's own private names are its business.
    frames = tree("muble_plugins/objects/frames.py", "def _rim(): ...\ndef rim(): ...\n")
    cache = tree("muble_plugins/objects/_cache.py", "TABLE = {}\n")
    own = tree("muble_plugins/objects/sets.py", "from muble_plugins.objects.frames import _rim\n"
                                                "from ._cache import TABLE\n")
    grasp = tree("muble_plugins/tasks/grasp.py", "from muble_plugins.objects.frames import rim, _rim\n"
                                                 "import muble_plugins.objects._cache\n")
    learned = tree("muble_plugins/learned/x.py", "def f():\n    from ..objects._cache import TABLE\n"
                                                 "from muble_plugins.objects import frames, __version__\n")
    shared = tree("muble_plugins/common/books.py", "from muble_plugins.objects.frames import rim\n")
    files = [plan, oracle, names, frames, cache, own, grasp, learned, shared]
    assert cycles(files) == [
        ["muble.core.names", "muble_plugins.tasks.plan", "muble.core.names"],
        ["muble_plugins.tasks.plan", "muble_plugins.agents.oracle", "muble_plugins.tasks.plan"]]
    assert private_imports(files) == [
        "muble_plugins/tasks/grasp.py:1: muble_plugins.tasks.grasp imports muble_plugins.objects.frames._rim, "
        "private to muble_plugins.objects: make it public there or move it to muble_plugins.common",
        "muble_plugins/tasks/grasp.py:2: muble_plugins.tasks.grasp imports muble_plugins.objects._cache, "
        "private to muble_plugins.objects: make it public there or move it to muble_plugins.common",
        "muble_plugins/learned/x.py:2: muble_plugins.learned.x imports muble_plugins.objects._cache.TABLE, "
        "private to muble_plugins.objects: make it public there or move it to muble_plugins.common"]
    assert rule_violations(files) == [
        "muble/core/names.py:3: muble.core.names imports muble_plugins.tasks.plan: the core knows plugins only "
        "through the registry, by name",
        "muble_plugins/common/books.py:1: muble_plugins.common.books imports muble_plugins.objects.frames: the "
        "shared package is what the plugins import; it imports none of them"]
    assert len(findings(files)) == 2 + 3 + 2
    # Without the planted imports, the same files pass.
    fixed = [tree("muble_plugins/agents/oracle.py", "class Oracle: ...\n"),
             tree("muble/core/names.py", "NAMES = ()\n"),
             tree("muble_plugins/tasks/grasp.py", "from muble_plugins.objects.frames import rim\n"),
             tree("muble_plugins/learned/x.py", "from muble_plugins.objects import frames\n"),
             tree("muble_plugins/common/books.py", "RETRY_LIMIT = 16\n")]
    _tree.cache_clear()
    assert findings([plan, frames, cache, own, *fixed]) == []


def test_a_lazy_import_against_a_plugin_rule_is_found(tree):
    path = tree("muble_plugins/tasks/x.py", "def f():\n    from muble.generation.scene import generate\n")
    assert rule_violations([path]) == ["muble_plugins/tasks/x.py:2: muble_plugins.tasks.x imports "
                                       "muble.generation.scene: plugins do not generate scenes; the core calls them"]


def test_an_exception_that_excuses_nothing_is_reported(tree, monkeypatch):
    needed = tree("muble/sim/lazy.py", "def f():\n    from muble.app.run import job\n")
    downward = tree("muble/app/fine.py", "from muble.sim import lazy\n")
    monkeypatch.setitem(globals(), "EXCEPTIONS", {
        ("muble/sim/lazy.py", "muble.app.run"): "needed: an upward import",
        ("muble/app/fine.py", "muble.sim.lazy"): "not needed: a downward import breaks no rule",
        ("muble/app/fine.py", "muble.core.gone"): "not needed: no such import"})
    assert unneeded_exceptions([needed, downward]) == [
        "('muble/app/fine.py', 'muble.sim.lazy'): breaks no rule",
        "('muble/app/fine.py', 'muble.core.gone'): the import is gone"]
    assert layer_violations([needed, downward]) == []


def test_a_plugin_name_used_as_one_is_found(tree):
    path = tree("muble/episode/bad.py", 'A, B = "move", "lift"\n'
                                        'def f(registry, call, object_set="shopvrb2"):\n'
                                        '    registry.create("renderer", "mujoco", {})\n'
                                        '    return call.name == "weigh"\n'
                                        'TITLE = "move"  # a word, not a plugin name\n'
                                        'parser.add_argument("--object-set", default="shopvrb2")\n'
                                        'parser.add_argument("--title", default="move")\n'
                                        'make(planner="ompl", title="lift")\n')
    found = plugin_name_uses(path, {"move", "lift", "shopvrb2", "mujoco", "weigh", "ompl"})
    assert sorted(found) == [(1, "lift"), (1, "move"), (2, "shopvrb2"), (3, "mujoco"), (4, "weigh"),
                             (6, "shopvrb2"), (8, "ompl")]


def test_a_definition_named_after_a_primitive_is_found(tree):
    path = tree("muble/sim/bad.py", "class Env:\n    def weigh(self):\n        pass\n    shake = None\n"
                                    "    def open_gripper(self):\n        pass\n"
                                    "def balance(env):\n    pass\n"
                                    "def hold(env):\n    pass\n")
    found = primitive_definitions([path], {"weigh", "shake", "balance", "open_gripper"})
    why = "is a built-in primitive: its procedure belongs in the primitive, written against the environment's " \
          "sensing API (docs/plugins.md)"
    assert found == [f"muble/sim/bad.py:2: 'weigh' {why}", f"muble/sim/bad.py:4: 'shake' {why}",
                     f"muble/sim/bad.py:5: 'open_gripper' {why}", f"muble/sim/bad.py:7: 'balance' {why}"]
    # The environment's own actuator commands are excused by name and file only.
    other = tree("muble/sim/env.py", "class Env:\n    def open_gripper(self):\n        pass\n")
    assert primitive_definitions([other], {"open_gripper"}) == []


def test_the_architecture_picture_is_the_code_s():
    """docs/images/architecture.svg is drawn from the imports by scripts/architecture_picture.py: an import that
    adds or removes an arrow between packages fails here until the picture is drawn again."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "architecture_picture.py"), "--check"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_the_architecture_picture_shows_a_planted_import(tmp_path):
    """The picture follows the code: a new package importing the core gets a box and an arrow."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("architecture_picture", ROOT / "scripts" / "architecture_picture.py")
    picture = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(picture)
    counts, edges = picture.graph()
    assert ("muble.app", "muble.core") in edges and ("muble.core", "muble.app") not in edges
    drawn = picture.svg({**counts, "muble.extra": 1}, edges | {("muble.extra", "muble.core")})
    assert ">muble.extra<" in drawn and "muble.extra imports muble.core" in drawn
    assert drawn != picture.svg(counts, edges)
