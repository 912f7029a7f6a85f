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
heaviest/lightest of a set), ``{members_in: [O1s, TP]}`` (the set's objects in a table part), ``{opposite: TP}``,
``{friction_extreme: [O1s, FS]}`` (likewise ``stiffness_extreme``, ``com_offset_extreme``) and ``{having: [O1s,
rattles]}`` (the set's objects that have a yes/no property).
Constraint types: ``is`` (an object, or every object of a set, has ``property``), ``max_count``, ``distinct``,
``not_tp``, ``tp_set`` (the set's objects in the part: at least one, all with ``property``), ``weight_extreme``,
``weight_order``, ``stack_order`` (heaviest first: all but the last are stack bases, all but the first
stackable), ``related`` (``[A, REL, B]``: B is REL of A), their stiffness counterparts ``stiffness_extreme``,
``stiffness_order``, ``stiffness_stack_order`` and the same for ``friction`` and ``com_offset``
(``friction_extreme`` …; each quantity's margin in ``templates.MARGINS``), ``carries`` (an object, or every object of
a set, has a ground truth of the measured ``property``: ``{type: carries, target: O1, property: friction}``),
``mixed`` (a set has members with and members without the yes/no ``property``, e.g. ``rattles``), ``among`` (an
object, or every object of a set, has an attribute ``property`` among ``values``: ``{type: among, target: O1s, property: model, values: [mug1, glass2]}``), and the
dear ``room`` (``[movers, part]``). A mistake in a file is
a ``ConfigError`` naming the file, the template and the field.
"""
from __future__ import annotations

import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

from muble import ConfigError
from muble.core.errors import unknown_name
from muble.io.instructions_io import program_step
from muble.programs.descriptions import ATTRIBUTE_STEP, describe
from muble.core.physical_properties import Derived
from muble.programs.program import QUANTITIES, RELATIONS, related
from muble.stage.table import OPPOSITE_PART

# Templates name the four sides of the table, never "centre".
# Each registered property's superlatives are a domain (``Property.domain``: ``weight_superlative``,
# ``com_superlative`` …).
WORD_DOMAINS: Mapping[str, tuple[str, ...]] = Derived(lambda props: {
    "table_part": tuple(OPPOSITE_PART), **{p.domain: p.superlatives for p in props.values() if p.domain},
    "relation": tuple(RELATIONS)})
# Measured quantities (besides the weight) that templates compare: <q>_extreme references and constraints,
# <q>_order and <q>_stack_order constraints, each with the quantity's margin (``templates.MARGINS``).
COMPARED: Mapping[str, Any] = Derived(lambda props: {n: p for n, p in props.items() if p.compared})
PARAMETER_TYPES: Mapping[str, Any] = Derived(lambda props: dict.fromkeys(("object", "objects", *WORD_DOMAINS)))
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


# ---------------------------------------------------------------------------------------- interpretation
# Each reference and constraint of a template is read once into a function of (bound parameters, option context),
# chosen by its type from the tables below; generation then only calls them (hundreds of thousands of times), and
# no source is generated or run.
Ref = Callable[[dict, Any], Any]
Check = Callable[[dict, Any], bool]
PROPERTIES = ("pickupable", "stackable", "stack_base")  # what ``is`` and ``tp_set`` may look at
ATTRIBUTES = ("model", "name", "shape", "size", "material", "colour")  # what ``among`` may look at


def _name(ref: str) -> str:
    return ref[1:-1] if ref.startswith("<") and ref.endswith(">") else ref


def compile_ref(ref: Any) -> Ref:
    """A reference (see the module doc) as a function of (bound parameters, option context)."""
    if isinstance(ref, str):
        name = _name(ref)
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
            if kind.endswith("_extreme") and kind[:-len("_extreme")] in COMPARED:
                quantity = kind[:-len("_extreme")]
                return lambda b, c: c.quantity_extreme(quantity, first(b, c), second(b, c))
            if kind == "having":  # the set's members that have a yes/no quantity: {having: [O1s, rattles]}
                return lambda b, c: c.having(second(b, c), first(b, c)) or []
            if kind == "members_in":
                return lambda b, c: [i for i in first(b, c) if second(b, c) in c.parts(i)]
            if kind == "related":
                return lambda b, c: related(c.index.scene, first(b, c), second(b, c))
    raise ConfigError(f"unknown reference {ref!r}; use a parameter name or one of extreme, "
                      f"{', '.join(q + '_extreme' for q in COMPARED)}, having, members_in, opposite, related")


def _refs(x: Any) -> list[str]:
    """Every parameter name a reference mentions."""
    if isinstance(x, str):
        return [_name(x)]
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


def _property(k: dict, allowed: tuple[str, ...], what: str = "property") -> str:
    if k.get("property") not in allowed:
        raise ConfigError(unknown_name(what, str(k.get("property")), allowed))
    return k["property"]


def _values(k: dict) -> frozenset[str]:
    values = k.get("values")
    if not isinstance(values, list) or not values or not all(isinstance(v, str) for v in values):
        raise ConfigError(f"constraint among needs values: a non-empty list of words, got {values!r}")
    return frozenset(values)


# Each constraint type: (how many references its target holds, a factory of its check from (the constraint's
# entry, its target's references, the template's parameter kinds)).
def _is(k, refs, kinds):
    (value,), prop, target = refs, _property(k, PROPERTIES), k["target"]
    plain = kinds.get(_refs(target)[0]) if isinstance(target, str) else None
    if plain == "object":
        return lambda b, c: getattr(c.obj(value(b, c)), prop)
    if plain is not None:
        return lambda b, c: all(getattr(c.obj(i), prop) for i in value(b, c))

    def check(b, c):  # a derived reference: an object, a set, or None (no such object): false
        found = value(b, c)
        if found is None:
            return False
        if isinstance(found, int):
            return getattr(c.obj(found), prop)
        return all(getattr(c.obj(i), prop) for i in found)
    return check


def _among(k, refs, kinds):
    (value,), attribute, values = refs, _property(k, ATTRIBUTES, "attribute"), _values(k)
    return lambda b, c: all(getattr(c.obj(i), attribute) in values for i in _members(value(b, c)))


def _count(within):
    def make(k, refs, kinds):
        (value,), limit = refs, int(k["value"])
        return lambda b, c: within(len(value(b, c)), limit)
    return make


def _distinct(k, refs, kinds):
    first, second = refs
    if kinds.get(_refs(k["target"][1])[0]) == "object":
        return lambda b, c: first(b, c) != second(b, c)
    return lambda b, c: first(b, c) not in second(b, c)


def _not_tp(k, refs, kinds):
    obj, part = refs
    return lambda b, c: all(part(b, c) not in c.parts(i) for i in _members(obj(b, c)))


def _quantity(k: dict, yes_no: bool) -> str:
    """The measured quantity a constraint names (``property``): a yes/no one, or one that carries values."""
    allowed = tuple(n for n, q in QUANTITIES.items() if (not q.superlatives) == yes_no)
    return _property(k, allowed if yes_no else tuple(QUANTITIES), "measured property")


def _carries(k, refs, kinds):
    (value,), quantity = refs, _quantity(k, yes_no=False)
    return lambda b, c: all(c.value(quantity, i) is not None for i in _members(value(b, c)))


def _mixed(k, refs, kinds):
    (value,), quantity = refs, _quantity(k, yes_no=True)

    def check(b, c):
        group = _members(value(b, c))
        yes = c.having(quantity, group)
        return yes is not None and 0 < len(yes) < len(group)
    return check


def _tp_set(k, refs, kinds):
    (group, part), prop = refs, _property(k, PROPERTIES)

    def check(b, c):
        where = part(b, c)
        inside = [i for i in group(b, c) if where in c.parts(i)]
        return bool(inside) and all(getattr(c.obj(i), prop) for i in inside)
    return check


def _pair(method, *first):
    def make(k, refs, kinds):
        group, which = refs
        return lambda b, c: getattr(c, method)(*first, group(b, c), which(b, c)) is not None
    return make


def _ranked(method, stack, *first):
    def make(k, refs, kinds):
        (group,) = refs
        if stack:
            return lambda b, c: _ranked_ok(c, getattr(c, method)(*first, group(b, c)))
        return lambda b, c: getattr(c, method)(*first, group(b, c)) is not None
    return make


def _related(k, refs, kinds):
    anchor, relation, other = refs
    return lambda b, c: other(b, c) in related(c.index.scene, anchor(b, c), relation(b, c))


def _room(k, refs, kinds):
    movers, part = refs
    return lambda b, c: c.room(_members(movers(b, c)), part(b, c))


CONSTRAINTS: Mapping[str, tuple[int, Callable[[dict, list, dict], Check]]] = Derived(lambda props: {
    "is": (1, _is),
    "max_count": (1, _count(lambda n, v: n <= v)),
    "min_count": (1, _count(lambda n, v: n >= v)),
    "distinct": (2, _distinct),
    "not_tp": (2, _not_tp),
    "tp_set": (2, _tp_set),
    "weight_extreme": (2, _pair("extreme")),
    "weight_order": (1, _ranked("by_weight", stack=False)),
    "stack_order": (1, _ranked("by_weight", stack=True)),
    **{f"{q}_extreme": (2, _pair("quantity_extreme", q)) for q in COMPARED},
    **{f"{q}_order": (1, _ranked("by_quantity", False, q)) for q in COMPARED},
    **{f"{q}_stack_order": (1, _ranked("by_quantity", True, q)) for q in COMPARED},
    "carries": (1, _carries),
    "mixed": (1, _mixed),
    "related": (3, _related),
    "among": (1, _among),
})
# Dear constraints are checked only for the options the generator samples (``DataTemplate.feasible``).
DEAR_CONSTRAINTS: dict[str, tuple[int, Callable[[dict, list, dict], Check]]] = {"room": (2, _room)}


def read_constraint(k: dict, kinds: dict[str, str]) -> Check:
    """The check of a constraint entry (its ``type`` one of ``CONSTRAINTS`` or ``DEAR_CONSTRAINTS``) for a
    template whose parameters have ``kinds``."""
    needs, make = {**CONSTRAINTS, **DEAR_CONSTRAINTS}[k["type"]]
    target = k.get("target")
    targets = target if isinstance(target, list) else [target]
    if len(targets) != needs:
        raise ConfigError(f"constraint {k['type']} needs a target of {needs} reference(s), got {target!r}")
    return make(k, [compile_ref(t) for t in targets], kinds)


# ---------------------------------------------------------------------------------------------- machinery
class DataTemplate:
    """The callables the generator uses (options, feasibility, text slots and program) for one ``TemplateSpec``."""

    def __init__(self, spec: TemplateSpec):
        self.spec = spec
        self.names = [n for n, _ in spec.parameters]
        self.described = [n for n, kind in spec.parameters if kind in ("object", "objects")]
        self.slots = [(n, kind == "objects") for n, kind in spec.parameters]
        # Phrasings as format strings (braces of the text escaped), program steps with their references read.
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
        # Each cheap constraint is checked as soon as the parameters it names are bound; one that names a single
        # parameter filters that parameter's values once per scene. Dear ones wait for ``feasible``.
        kinds = dict(spec.parameters)
        self.at: list[list[Check]] = [[] for _ in self.names]
        self.unary: list[list[Check]] = [[] for _ in self.names]
        self.dear: list[Check] = []
        for k in spec.constraints:
            check = read_constraint(k, kinds)
            named = [n for n in _refs(k.get("target")) if n in kinds]
            if k["type"] in DEAR_CONSTRAINTS:
                self.dear.append(check)
            else:
                depth = max((self.names.index(n) for n in named), default=0)
                (self.unary if len(set(named)) == 1 else self.at)[depth].append(check)

    def _domain(self, kind: str, c: Any) -> list[Any]:
        if kind == "object":
            return list(c.index.unique)
        if kind == "objects":
            return list(c.index.groups)
        return list(WORD_DOMAINS[kind])

    def options(self, c: Any) -> Iterator[tuple]:
        """Every binding of the parameters, in their order, that passes the cheap constraints."""
        names, last = self.names, len(self.names) - 1
        if not names:
            return iter([()])
        domains = []
        for depth, (name, kind) in enumerate(self.spec.parameters):
            values, checks = self._domain(kind, c), self.unary[depth]
            if checks:
                values = [v for v in values if all(check({name: v}, c) for check in checks)]
            domains.append(values)
        bound: dict[str, Any] = {}
        out: list[tuple] = []

        def walk(depth: int) -> None:
            name, checks = names[depth], self.at[depth]
            for value in domains[depth]:
                bound[name] = value
                if checks and not all(check(bound, c) for check in checks):
                    continue
                if depth == last:
                    out.append(tuple(bound[n] for n in names))
                else:
                    walk(depth + 1)

        walk(0)
        return iter(out)

    def feasible(self, option: tuple, c: Any) -> bool:
        """Whether ``option`` passes the dear constraints too."""
        bound = dict(zip(self.names, option))
        return all(check(bound, c) for check in self.dear)

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
