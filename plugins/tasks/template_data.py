"""Task templates as data: a YAML or JSON file of templates, read into the shared generation machinery.

A template file holds ``templates:``, a list of entries::

    template_id: move_single          # the task plugin's name
    task_id: move                     # the task type the report groups by
    index: 3                          # template_overall_idx in instruction files
    description: move one object to a table part
    text:                             # phrasings; <NAME> is a parameter, [word] an optional word
      - "Move the <O1> to the <TP> part of the table."
    parameters:                       # enumerated in this order (the options' order)
      - {name: O1, type: object}      # object: described uniquely; objects: a set, described in the plural;
      - {name: TP, type: table_part}  # table_part, weight_superlative, stiffness_superlative, relation: words
    constraints:                      # cheap filters on options, checked as soon as their parameters are bound
      - {type: is, target: O1, property: pickupable}
      - {type: not_tp, target: [O1, TP]}
      - {type: room, target: [O1, TP]} # dear: checked only for the options the generator samples
    program:                          # CLEVR-IEP steps; {describe: O1} = the filters of O1's description
      - {type: scene}
      - {describe: O1}
      - {type: move_to, input_value: <TP>}

References (``target``, ``input_value``): a parameter name, or a derived value ``{extreme: [O1s, WS]}`` (the
heaviest/lightest of a set), ``{members_in: [O1s, TP]}`` (the set's objects in a table part), ``{opposite: TP}``.
Constraint types: ``is`` (an object, or every object of a set, has ``property``), ``max_count``, ``distinct``,
``not_tp``, ``tp_set`` (the set's objects in the part: at least one, all with ``property``), ``weight_extreme``,
``weight_order``, ``stack_order`` (heaviest first: all but the last are stack bases, all but the first
stackable), ``related`` (``[A, REL, B]``: B is REL of A), their stiffness counterparts ``stiffness_extreme``,
``stiffness_order``, ``stiffness_stack_order``, and the dear ``room`` (``[movers, part]``). A mistake in a file is
a ``ConfigError`` naming the file, the template and the field.
"""
from __future__ import annotations

import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

from muble import ConfigError
from muble.core.errors import unknown_name
from muble.core.instructions_io import program_step
from muble.core.program import OPPOSITE_PART, RELATIONS, related

from muble_plugins.tasks.vocabulary import ATTRIBUTE_STEP, describe

TABLE_PARTS = ("left", "right", "front", "back")
SUPERLATIVES = ("heaviest", "lightest")
STIFFNESS_SUPERLATIVES = ("hardest", "softest")
WORD_DOMAINS = {"table_part": TABLE_PARTS, "weight_superlative": SUPERLATIVES,
                "stiffness_superlative": STIFFNESS_SUPERLATIVES, "relation": tuple(RELATIONS)}
PARAMETER_TYPES = ("object", "objects", *WORD_DOMAINS)
_TOKEN = re.compile(r"<([A-Za-z0-9_]+)>")
_OPTIONAL = re.compile(r"\[([^\]]+)\] ?")


def expand_optional_words(text: str) -> list[str]:
    """Every phrasing a text with optional words (``[word] ``) stands for, the fullest first."""
    parts = _OPTIONAL.split(text)
    words, pieces = parts[1::2], parts[0::2]
    out = []
    for keep in itertools.product((True, False), repeat=len(words)):
        text_ = pieces[0] + "".join((f"{w} " if k else "") + p for w, k, p in zip(words, keep, pieces[1:]))
        out.append(" ".join(text_.split()).replace(" .", ".").replace(" ?", "?"))
    return list(dict.fromkeys(out))


@dataclass(frozen=True)
class TemplateSpec:
    """One template as read from a file (see the module doc)."""

    template_id: str
    task_id: str
    index: int
    description: str
    texts: tuple[str, ...]
    parameters: tuple[tuple[str, str], ...]  # (name, type)
    constraints: tuple[dict[str, Any], ...]
    program: tuple[dict[str, Any], ...]
    source: str = ""


# ------------------------------------------------------------------------------------------------ references
def _value(ref: Any, bound: dict[str, Any], c: Any) -> Any:
    if isinstance(ref, str):
        name = ref[1:-1] if ref.startswith("<") and ref.endswith(">") else ref
        return bound.get(name, name)  # not a parameter: a literal word ("left", "ascending")
    if isinstance(ref, dict) and len(ref) == 1:
        (kind, args), = ref.items()
        if kind == "extreme":
            return c.extreme(_value(args[0], bound, c), _value(args[1], bound, c))
        if kind == "stiffness_extreme":
            return c.stiffness_extreme(_value(args[0], bound, c), _value(args[1], bound, c))
        if kind == "members_in":
            part = _value(args[1], bound, c)
            return [i for i in _value(args[0], bound, c) if part in c.parts(i)]
        if kind == "opposite":
            return OPPOSITE_PART[_value(args, bound, c)]
        if kind == "related":
            return related(c.index.scene, _value(args[0], bound, c), _value(args[1], bound, c))
    raise ConfigError(f"unknown reference {ref!r}; use a parameter name or one of extreme, stiffness_extreme, "
                      "members_in, opposite, related")


def _refs(x: Any) -> list[str]:
    """Every parameter name a reference mentions."""
    if isinstance(x, str):
        return [x[1:-1] if x.startswith("<") and x.endswith(">") else x]
    if isinstance(x, dict):
        return [n for v in x.values() for n in _refs(v)]
    if isinstance(x, (list, tuple)):
        return [n for v in x for n in _refs(v)]
    return []


def _members(value: Any) -> list[int]:
    return [value] if isinstance(value, int) else list(value)


def _ranked_ok(c: Any, ranked: list[int] | None) -> bool:
    return ranked is not None and all(c.obj(i).stack_base for i in ranked[:-1]) \
        and all(c.obj(i).stackable for i in ranked[1:])


CONSTRAINTS: dict[str, Callable[[dict, Callable[[Any], Any], Any], bool]] = {
    "is": lambda k, v, c: all(getattr(c.obj(i), k["property"]) for i in _members(v(k["target"]))),
    "max_count": lambda k, v, c: len(v(k["target"])) <= int(k["value"]),
    "min_count": lambda k, v, c: len(v(k["target"])) >= int(k["value"]),
    "distinct": lambda k, v, c: (lambda a, b: a != b if isinstance(b, int) else a not in b)(
        v(k["target"][0]), v(k["target"][1])),
    "not_tp": lambda k, v, c: v(k["target"][1]) not in c.parts(v(k["target"][0])),
    "tp_set": lambda k, v, c: (lambda inside: bool(inside) and all(getattr(c.obj(i), k["property"]) for i in inside))(
        [i for i in v(k["target"][0]) if v(k["target"][1]) in c.parts(i)]),
    "weight_extreme": lambda k, v, c: c.extreme(v(k["target"][0]), v(k["target"][1])) is not None,
    "weight_order": lambda k, v, c: c.by_weight(v(k["target"])) is not None,
    "stack_order": lambda k, v, c: _ranked_ok(c, c.by_weight(v(k["target"]))),
    "stiffness_extreme": lambda k, v, c: c.stiffness_extreme(v(k["target"][0]), v(k["target"][1])) is not None,
    "stiffness_order": lambda k, v, c: c.by_stiffness(v(k["target"])) is not None,
    "stiffness_stack_order": lambda k, v, c: _ranked_ok(c, c.by_stiffness(v(k["target"]))),
    "related": lambda k, v, c: v(k["target"][2]) in related(c.index.scene, v(k["target"][0]), v(k["target"][1])),
}
DEAR_CONSTRAINTS = {"room": lambda k, v, c: c.room(_members(v(k["target"][0])), v(k["target"][1]))}


# ---------------------------------------------------------------------------------------------- machinery
class DataTemplate:
    """The callables the generator uses (options, feasibility, text slots and program) for one ``TemplateSpec``."""

    def __init__(self, spec: TemplateSpec):
        self.spec = spec
        self.names = [n for n, _ in spec.parameters]
        cheap = [k for k in spec.constraints if k["type"] in CONSTRAINTS]
        self.dear = [k for k in spec.constraints if k["type"] in DEAR_CONSTRAINTS]
        # Each cheap constraint is checked at the first parameter after which it can be evaluated.
        self.at: list[list[dict]] = [[] for _ in self.names]
        for k in cheap:
            self.at[self._ready(k)].append(k)

    def _ready(self, constraint: dict) -> int:
        needed = [n for n in _refs(constraint.get("target")) if n in self.names]
        return max(self.names.index(n) for n in needed) if needed else 0

    def _domain(self, kind: str, c: Any) -> list[Any]:
        if kind == "object":
            return list(c.index.unique)
        if kind == "objects":
            return list(c.index.groups)
        return list(WORD_DOMAINS[kind])

    def options(self, c: Any) -> Iterator[tuple]:
        bound: dict[str, Any] = {}

        def holds(k: dict) -> bool:
            return CONSTRAINTS[k["type"]](k, lambda ref: _value(ref, bound, c), c)

        def walk(depth: int) -> Iterator[tuple]:
            if depth == len(self.names):
                yield tuple(bound[n] for n in self.names)
                return
            name, kind = self.spec.parameters[depth]
            for value in self._domain(kind, c):
                bound[name] = value
                if all(holds(k) for k in self.at[depth]):
                    yield from walk(depth + 1)
            bound.pop(name, None)

        yield from walk(0)

    def feasible(self, option: tuple, c: Any) -> bool:
        bound = dict(zip(self.names, option))
        return all(DEAR_CONSTRAINTS[k["type"]](k, lambda ref: _value(ref, bound, c), c) for k in self.dear)

    def build(self, option: tuple, descriptions: list) -> tuple[dict[str, str], list[dict[str, Any]]]:
        """Text slots and the program (without outputs) of an option with its chosen descriptions."""
        bound = dict(zip(self.names, option))
        described = {}
        k = 0
        for name, kind in self.spec.parameters:
            if kind in ("object", "objects"):
                described[name] = descriptions[k]
                k += 1
        slots = {}
        for name, kind in self.spec.parameters:
            slots[name] = describe(described[name], many=kind == "objects") if name in described else bound[name]
        program = []
        for step in self.spec.program:
            if "describe" in step:
                program += [program_step(ATTRIBUTE_STEP[a], input_value=v) for a, v in described[step["describe"]]]
                continue
            value = step.get("input_value")
            if isinstance(value, dict) or (isinstance(value, str) and value.startswith("<")):
                value = _value(value, bound, None)  # a parameter (<TP>) or a derived word ({opposite: TP})
            program.append(program_step(step["type"], input_value=value))
        return slots, program

    @staticmethod
    def fill(text: str, slots: dict[str, str]) -> str:
        return _TOKEN.sub(lambda m: str(slots[m.group(1)]), text)


# ------------------------------------------------------------------------------------------------ reading
def _fail(source: str, template: str, field: str, message: str) -> ConfigError:
    return ConfigError(f"{source}: template '{template}', field '{field}': {message}")


def template_from_dict(d: Any, source: str = "<data>") -> TemplateSpec:
    """One template entry, checked (see the module doc)."""
    if not isinstance(d, dict):
        raise ConfigError(f"{source}: a template must be a mapping, got {type(d).__name__}")
    name = str(d.get("template_id", "?"))
    for key in ("template_id", "task_id", "text", "parameters", "program"):
        if key not in d:
            raise _fail(source, name, key, "missing")
    texts = d["text"]
    if not isinstance(texts, list) or not texts or not all(isinstance(t, str) for t in texts):
        raise _fail(source, name, "text", "expected a non-empty list of phrasings")
    params = []
    for p in d["parameters"]:
        if not isinstance(p, dict) or p.get("type") not in PARAMETER_TYPES or not isinstance(p.get("name"), str):
            raise _fail(source, name, "parameters", f"{p!r}: each needs a name and a type, one of "
                                                     f"{', '.join(PARAMETER_TYPES)}")
        params.append((p["name"], p["type"]))
    names = [n for n, _ in params]
    constraints = []
    for k in d.get("constraints", []):
        if not isinstance(k, dict) or k.get("type") not in {**CONSTRAINTS, **DEAR_CONSTRAINTS}:
            kind = k.get("type") if isinstance(k, dict) else k
            raise _fail(source, name, "constraints",
                        unknown_name("constraint type", str(kind), [*CONSTRAINTS, *DEAR_CONSTRAINTS]))
        constraints.append(k)
    program = []
    for step in d["program"]:
        if not isinstance(step, dict) or not ("type" in step or "describe" in step):
            raise _fail(source, name, "program", f"{step!r}: a step needs a type (or describe: PARAMETER)")
        if "describe" in step and step["describe"] not in names:
            raise _fail(source, name, "program", unknown_name("parameter", str(step["describe"]), names))
        program.append(step)
    texts_ = [v for t in texts for v in expand_optional_words(t)]
    for t in texts_:
        for token in _TOKEN.findall(t):
            if token not in names:
                raise _fail(source, name, "text", f"'{t}': " + unknown_name("parameter", token, names))
    return TemplateSpec(name, str(d["task_id"]), int(d.get("index", -1)), str(d.get("description", name)),
                        tuple(texts_), tuple(params), tuple(constraints), tuple(program), source)


def read_template_file(path: str | Path) -> list[TemplateSpec]:
    """The templates of a YAML (``.yaml``/``.yml``) or JSON file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
        if path.suffix in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text)
        else:
            data = json.loads(text)
    except (OSError, ValueError) as e:
        raise ConfigError(f"cannot read template file {path}: {type(e).__name__}: {e}") from e
    entries = data.get("templates") if isinstance(data, dict) else data
    if not isinstance(entries, list):
        raise ConfigError(f"{path}: expected a list of templates under 'templates:'")
    specs = [template_from_dict(d, str(path)) for d in entries]
    ids = [s.template_id for s in specs]
    doubled = sorted({i for i in ids if ids.count(i) > 1})
    if doubled:
        raise ConfigError(f"{path}: template ids {doubled} appear more than once")
    return specs
