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
``stiffness_order``, ``stiffness_stack_order``, ``among`` (an object, or every object of a set, has an attribute
``property`` among ``values``: ``{type: among, target: O1s, property: model, values: [mug1, glass2]}``), and the
dear ``room`` (``[movers, part]``). A mistake in a file is
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
from muble.core.descriptions import ATTRIBUTE_STEP, describe
from muble.core.errors import unknown_name
from muble.core.instructions_io import program_step
from muble.core.program import RELATIONS, STIFFNESS_SUPERLATIVES, WEIGHT_SUPERLATIVES, related
from muble.core.table import OPPOSITE_PART

# Templates name the four sides of the table, never "centre".
WORD_DOMAINS = {"table_part": tuple(OPPOSITE_PART), "weight_superlative": WEIGHT_SUPERLATIVES,
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
# References and constraints are compiled once into closures of (bound parameters, option context): generation
# checks them hundreds of thousands of times.
Ref = Callable[[dict, Any], Any]


def compile_ref(ref: Any) -> Ref:
    """A reference (see the module doc) as a function of (bound parameters, option context)."""
    if isinstance(ref, str):
        name = ref[1:-1] if ref.startswith("<") and ref.endswith(">") else ref
        return lambda b, c: b.get(name, name)  # not a parameter: a literal word ("left", "ascending")
    if isinstance(ref, dict) and len(ref) == 1:
        (kind, args), = ref.items()
        if kind == "opposite":
            part = compile_ref(args)
            return lambda b, c: OPPOSITE_PART[part(b, c)]
        if isinstance(args, list) and len(args) == 2:
            first, second = compile_ref(args[0]), compile_ref(args[1])
            if kind == "extreme":
                return lambda b, c: c.extreme(first(b, c), second(b, c))
            if kind == "stiffness_extreme":
                return lambda b, c: c.stiffness_extreme(first(b, c), second(b, c))
            if kind == "members_in":
                return lambda b, c: [i for i in first(b, c) if second(b, c) in c.parts(i)]
            if kind == "related":
                return lambda b, c: related(c.index.scene, first(b, c), second(b, c))
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


def _targets(k: dict, n: int) -> list[Ref]:
    target = k["target"]
    if n == 1:
        return [compile_ref(target)]
    if not isinstance(target, list) or len(target) != n:
        raise ConfigError(f"constraint {k['type']} needs a target of {n} references, got {target!r}")
    return [compile_ref(t) for t in target]


def _is(k):
    (t,), prop = _targets(k, 1), k["property"]

    def check(b, c):
        value = t(b, c)
        if isinstance(value, int):
            return getattr(c.obj(value), prop)
        return all(getattr(c.obj(i), prop) for i in value)
    return check


def _count(limit_ok):
    def make(k):
        (t,), value = _targets(k, 1), int(k["value"])
        return lambda b, c: limit_ok(len(t(b, c)), value)
    return make


def _distinct(k):
    first, second = _targets(k, 2)

    def check(b, c):
        x, y = first(b, c), second(b, c)
        return x != y if isinstance(y, int) else x not in y
    return check


def _not_tp(k):
    obj, part = _targets(k, 2)
    return lambda b, c: part(b, c) not in c.parts(obj(b, c))


def _tp_set(k):
    group, part = _targets(k, 2)
    prop = k["property"]

    def check(b, c):
        where = part(b, c)
        inside = [i for i in group(b, c) if where in c.parts(i)]
        return bool(inside) and all(getattr(c.obj(i), prop) for i in inside)
    return check


def _pair(method):
    def make(k):
        group, which = _targets(k, 2)
        return lambda b, c: getattr(c, method)(group(b, c), which(b, c)) is not None
    return make


def _ranked(method, stack):
    def make(k):
        (group,) = _targets(k, 1)
        if stack:
            return lambda b, c: _ranked_ok(c, getattr(c, method)(group(b, c)))
        return lambda b, c: getattr(c, method)(group(b, c)) is not None
    return make


def _among(k):
    (t,), prop, values = _targets(k, 1), _attribute(k), frozenset(_values(k))

    def check(b, c):
        return all(getattr(c.obj(i), prop) in values for i in _members(t(b, c)))
    return check


def _related(k):
    anchor, relation, other = _targets(k, 3)
    return lambda b, c: other(b, c) in related(c.index.scene, anchor(b, c), relation(b, c))


def _room(k):
    movers, part = _targets(k, 2)
    return lambda b, c: c.room(_members(movers(b, c)), part(b, c))


# Constraint type -> a factory of its check(bound, context) from the constraint's entry.
CONSTRAINTS: dict[str, Callable[[dict], Ref]] = {
    "is": _is,
    "max_count": _count(lambda n, v: n <= v),
    "min_count": _count(lambda n, v: n >= v),
    "distinct": _distinct,
    "not_tp": _not_tp,
    "tp_set": _tp_set,
    "weight_extreme": _pair("extreme"),
    "weight_order": _ranked("by_weight", stack=False),
    "stack_order": _ranked("by_weight", stack=True),
    "stiffness_extreme": _pair("stiffness_extreme"),
    "stiffness_order": _ranked("by_stiffness", stack=False),
    "stiffness_stack_order": _ranked("by_stiffness", stack=True),
    "related": _related,
    "among": _among,
}
DEAR_CONSTRAINTS: dict[str, Callable[[dict], Ref]] = {"room": _room}


# ------------------------------------------------------------------------------------------ compiled options
# Generation lists every option of every template for every scene, so a template's options are compiled once into
# plain nested loops (Python source built from the validated entry: parameter names are identifiers, words are
# repr()'d literals, properties one of PROPERTIES), as fast as hand-written ones.
PROPERTIES = ("pickupable", "stackable", "stack_base")
ATTRIBUTES = ("model", "name", "shape", "size", "material", "colour")  # what ``among`` may look at


def _attribute(k: dict) -> str:
    if k.get("property") not in ATTRIBUTES:
        raise ConfigError(unknown_name("attribute", str(k.get("property")), ATTRIBUTES))
    return k["property"]


def _values(k: dict) -> list[str]:
    values = k.get("values")
    if not isinstance(values, list) or not values or not all(isinstance(v, str) for v in values):
        raise ConfigError(f"constraint among needs values: a non-empty list of words, got {values!r}")
    return values


def _is_any(c: Any, value: Any, prop: str) -> bool:
    if value is None:
        return False
    if isinstance(value, int):
        return getattr(c.obj(value), prop)
    return all(getattr(c.obj(i), prop) for i in value)


def _tp_set_ok(c: Any, group: Any, part: str, prop: str) -> bool:
    inside = [i for i in group if part in c.parts(i)]
    return bool(inside) and all(getattr(c.obj(i), prop) for i in inside)


_HELPERS = {"_is_any": _is_any, "_tp_set_ok": _tp_set_ok, "_ranked_ok": _ranked_ok, "_members": _members,
            "related": related, "OPPOSITE": OPPOSITE_PART}


def _expr(ref: Any, kinds: dict[str, str]) -> str:
    """A reference as a Python expression over the loop variables ``p_<NAME>`` and the option context ``c``."""
    if isinstance(ref, str):
        name = ref[1:-1] if ref.startswith("<") and ref.endswith(">") else ref
        return f"p_{name}" if name in kinds else repr(name)
    if isinstance(ref, dict) and len(ref) == 1:
        (kind, args), = ref.items()
        if kind == "opposite":
            return f"OPPOSITE[{_expr(args, kinds)}]"
        if isinstance(args, list) and len(args) == 2:
            a, b = _expr(args[0], kinds), _expr(args[1], kinds)
            if kind in ("extreme", "stiffness_extreme"):
                return f"c.{kind}({a}, {b})"
            if kind == "members_in":
                return f"[i for i in {a} if {b} in c.parts(i)]"
            if kind == "related":
                return f"related(c.index.scene, {a}, {b})"
    raise ConfigError(f"unknown reference {ref!r}; use a parameter name or one of extreme, stiffness_extreme, "
                      "members_in, opposite, related")


def _condition(k: dict, kinds: dict[str, str]) -> str:
    """A constraint as a Python boolean expression (see ``_expr``)."""
    kind, target = k["type"], k.get("target")
    targets = target if isinstance(target, list) else [target]
    e = [_expr(t, kinds) for t in targets]
    needs = {"is": 1, "max_count": 1, "min_count": 1, "weight_order": 1, "stack_order": 1, "stiffness_order": 1,
             "stiffness_stack_order": 1, "distinct": 2, "not_tp": 2, "tp_set": 2, "weight_extreme": 2,
             "stiffness_extreme": 2, "room": 2, "related": 3, "among": 1}[kind]
    if len(e) != needs:
        raise ConfigError(f"constraint {kind} needs a target of {needs} reference(s), got {target!r}")
    if kind in ("is", "tp_set") and k.get("property") not in PROPERTIES:
        raise ConfigError(unknown_name("property", str(k.get("property")), PROPERTIES))
    plain = isinstance(target, str) and _refs(target)[0] in kinds
    if kind == "is":
        if plain and kinds[_refs(target)[0]] == "object":
            return f"c.obj({e[0]}).{k['property']}"
        if plain:
            return f"all(c.obj(i).{k['property']} for i in {e[0]})"
        return f"_is_any(c, {e[0]}, {k['property']!r})"
    if kind == "among":
        values = repr(frozenset(_values(k)))
        return f"all(c.obj(i).{_attribute(k)} in {values} for i in _members({e[0]}))"
    if kind in ("max_count", "min_count"):
        return f"len({e[0]}) {'<=' if kind == 'max_count' else '>='} {int(k['value'])}"
    if kind == "distinct":
        second = _refs(targets[1])[0]
        return f"{e[0]} != {e[1]}" if kinds.get(second) == "object" else f"{e[0]} not in {e[1]}"
    if kind == "not_tp":
        return f"{e[1]} not in c.parts({e[0]})"
    if kind == "tp_set":
        return f"_tp_set_ok(c, {e[0]}, {e[1]}, {k['property']!r})"
    if kind == "weight_extreme":
        return f"c.extreme({e[0]}, {e[1]}) is not None"
    if kind == "stiffness_extreme":
        return f"c.stiffness_extreme({e[0]}, {e[1]}) is not None"
    if kind in ("weight_order", "stiffness_order"):
        return f"c.{'by_weight' if kind == 'weight_order' else 'by_stiffness'}({e[0]}) is not None"
    if kind in ("stack_order", "stiffness_stack_order"):
        return f"_ranked_ok(c, c.{'by_weight' if kind == 'stack_order' else 'by_stiffness'}({e[0]}))"
    if kind == "related":
        return f"{e[2]} in related(c.index.scene, {e[0]}, {e[1]})"
    return f"c.room(_members({e[0]}), {e[1]})"  # room


def compile_options(spec: "TemplateSpec") -> tuple[Callable, Callable | None]:
    """(options(c) -> list of option tuples, feasible(option, c) -> bool or None) compiled from ``spec``."""
    kinds = dict(spec.parameters)
    names = list(kinds)
    at: list[list[str]] = [[] for _ in names]
    unary: list[list[str]] = [[] for _ in names]
    dear = []
    for k in spec.constraints:
        condition = _condition(k, kinds)
        if k["type"] in DEAR_CONSTRAINTS:
            dear.append(condition)
            continue
        named = [n for n in _refs(k.get("target")) if n in kinds]
        depth = max((names.index(n) for n in named), default=0)
        (unary if len(set(named)) == 1 else at)[depth].append(condition)
    domains = {"object": "c.index.unique", "objects": "c.index.groups"}
    lines = ["def options(c):", "    out = []"]
    for d, name in enumerate(names):
        domain = domains.get(kinds[name], repr(WORD_DOMAINS.get(kinds[name], ())))
        keep = " and ".join(unary[d]) or "True"
        lines.append(f"    D{d} = [p_{name} for p_{name} in {domain} if {keep}]")
    indent = "    "
    for d, name in enumerate(names):
        lines.append(f"{indent}for p_{name} in D{d}:")
        indent += "    "
        if at[d]:
            lines.append(f"{indent}if not ({' and '.join(at[d])}):")
            lines.append(f"{indent}    continue")
    lines.append(f"{indent}out.append(({''.join(f'p_{n}, ' for n in names)}))")
    lines.append("    return out")
    if dear:
        lines += ["def feasible(option, c):", f"    ({''.join(f'p_{n}, ' for n in names)}) = option",
                  f"    return {' and '.join(dear)}"]
    namespace = dict(_HELPERS)
    exec(compile("\n".join(lines), f"<template {spec.template_id}>", "exec"), namespace)  # noqa: S102
    return namespace["options"], namespace.get("feasible")


# ---------------------------------------------------------------------------------------------- machinery
class DataTemplate:
    """The callables the generator uses (options, feasibility, text slots and program) for one ``TemplateSpec``."""

    def __init__(self, spec: TemplateSpec):
        self.spec = spec
        self.names = [n for n, _ in spec.parameters]
        self.described = [n for n, kind in spec.parameters if kind in ("object", "objects")]
        self.slots = [(n, kind == "objects") for n, kind in spec.parameters]
        # Phrasings as format strings (braces of the text escaped), program steps with their references compiled.
        self.formats = {t: _TOKEN.sub(r"{\1}", t.replace("{", "{{").replace("}", "}}")) for t in spec.texts}
        self.steps = []
        for step in spec.program:
            value = step.get("input_value")
            if "describe" in step:
                self.steps.append((None, step["describe"]))
            elif isinstance(value, dict) or (isinstance(value, str) and value.startswith("<")):
                self.steps.append((step["type"], compile_ref(value)))  # a parameter (<TP>) or {opposite: TP}
            else:
                self.steps.append((step["type"], value))
        self.dear = [DEAR_CONSTRAINTS[k["type"]](k) for k in spec.constraints if k["type"] in DEAR_CONSTRAINTS]
        self._compiled, self._compiled_feasible = compile_options(spec)
        # Each cheap constraint is checked as soon as the parameters it names are bound; one that names a single
        # parameter filters that parameter's values once per scene.
        self.at: list[list[Ref]] = [[] for _ in self.names]
        self.unary: list[list[Ref]] = [[] for _ in self.names]
        for k in spec.constraints:
            if k["type"] in CONSTRAINTS:
                named = {n for n in _refs(k.get("target")) if n in self.names}
                (self.unary if len(named) == 1 else self.at)[self._ready(k)].append(CONSTRAINTS[k["type"]](k))

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
        return iter(self._compiled(c))

    def options_interpreted(self, c: Any) -> Iterator[tuple]:
        """The same options as ``options``, by the closures instead of the compiled loops (a cross-check)."""
        bound: dict[str, Any] = {}
        last = len(self.names) - 1
        domains = []
        for depth, (name, kind) in enumerate(self.spec.parameters):
            values = self._domain(kind, c)
            if self.unary[depth]:
                values = [v for v in values if all(check({name: v}, c) for check in self.unary[depth])]
            domains.append(values)

        names = self.names

        def walk(depth: int) -> list[tuple]:
            name, checks, out = names[depth], self.at[depth], []
            for value in domains[depth]:
                bound[name] = value
                for check in checks:
                    if not check(bound, c):
                        break
                else:
                    if depth == last:
                        out.append(tuple(bound[n] for n in names))
                    else:
                        out += walk(depth + 1)
            return out

        return iter(walk(0)) if names else iter(())

    def feasible(self, option: tuple, c: Any) -> bool:
        return self._compiled_feasible is None or self._compiled_feasible(option, c)

    def build(self, option: tuple, descriptions: list) -> tuple[dict[str, str], list[dict[str, Any]]]:
        """Text slots and the program (without outputs) of an option with its chosen descriptions."""
        bound = dict(zip(self.names, option))
        described = dict(zip(self.described, descriptions))
        slots = {name: describe(described[name], many=many) if name in described else bound[name]
                 for name, many in self.slots}
        program = []
        for kind, value in self.steps:
            if kind is None:  # {describe: NAME}
                program += [program_step(ATTRIBUTE_STEP[a], input_value=v) for a, v in described[value]]
            else:
                program.append(program_step(kind, input_value=value(bound, None) if callable(value) else value))
        return slots, program

    def fill(self, text: str, slots: dict[str, str]) -> str:
        """The phrasing ``text`` (one of the template's) with its parameters filled in."""
        return self.formats[text].format(**slots)


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
