"""From a model's reply to a decision: the first JSON object in the text, checked against the registered primitives.

A reply is one JSON object: an action ``{"name": "<primitive>", "params": {...}}``, an answer ``{"answer": ...}``
or ``{"stop": true}``. Whatever else the text holds around it (prose, a Markdown fence) is ignored, so a model that
explains itself still acts. What cannot be used raises ``ReplyError`` with a message meant for the model: it is
sent back so the model can correct itself. The same rules as a JSON schema (``decision_schema``) go to endpoints
that constrain their output, so a constrained reply always parses.
"""
from __future__ import annotations

import dataclasses
import json
from typing import Any, Sequence

from muble import ActionCall, Answer, ObservationMode, get_registry
from muble.core.params import Param, check_call
from muble.core.types import TABLE_PARTS

from muble_plugins.llm.prompt import primitive_params

FORMS = '{"name": "<primitive>", "params": {...}}, {"answer": [...]} or {"stop": true}'
STOP = "stop"
QUOTE = 80  # characters of a reply quoted in an error


class ReplyError(ValueError):
    """A reply that is not one usable decision; the message says what is wrong, for the model and the log, and
    ``kind`` names the fault in a few words, for the episode's record."""

    def __init__(self, message: str, kind: str) -> None:
        super().__init__(message)
        self.kind = kind


def _quote(text: str) -> str:
    text = " ".join(text.split())
    return repr(text if len(text) <= QUOTE else text[:QUOTE - 1] + "…")


def first_json_object(text: str) -> dict[str, Any]:
    """The first JSON object in ``text`` (the whole text when it is one)."""
    text = text.strip()
    try:
        whole = json.loads(text)
        if isinstance(whole, dict):
            return whole
    except json.JSONDecodeError:
        pass
    decoder = json.JSONDecoder()
    first_problem = None
    for start, char in enumerate(text):
        if char != "{":
            continue
        try:
            value, _ = decoder.raw_decode(text, start)
        except json.JSONDecodeError as e:
            first_problem = first_problem or e
            continue
        if isinstance(value, dict):
            return value
    if first_problem is not None:
        raise ReplyError(f"the JSON object in your reply does not parse ({first_problem.msg} at character "
                         f"{first_problem.pos}): {_quote(text)}", "JSON that does not parse")
    raise ReplyError(f"no JSON object in your reply: {_quote(text) if text else 'the reply is empty'}",
                     "no JSON object")


def _relaxed(params: Sequence[Param], view: ObservationMode) -> tuple[Param, ...]:
    """In image mode an object is a pixel, which the action loop resolves: only names and presence are checked."""
    if view != ObservationMode.image:
        return tuple(params)
    return tuple(dataclasses.replace(p, kind="any") if p.kind in ("object", "place") else p for p in params)


def decision_from(obj: dict[str, Any], view: ObservationMode, object_ids: Sequence[int]) -> ActionCall | Answer | None:
    """The decision a parsed reply states (None: stop), checked against the registry and the scene's ids."""
    keys = set(obj)
    if STOP in keys:
        if obj[STOP] is not True or keys != {STOP}:
            raise ReplyError(f'to stop, reply {{"stop": true}} alone; got {json.dumps(obj, default=str):.120}',
                             "another shape")
        return None
    if "answer" in keys:
        if keys != {"answer"}:
            raise ReplyError(f"an answer is {{\"answer\": ...}} alone; got keys {sorted(keys)}", "another shape")
        return Answer(obj["answer"])
    if "name" not in keys or not keys <= {"name", "params"}:
        raise ReplyError(f"expected {FORMS}; got keys {sorted(keys)}", "another shape")
    name, params = obj["name"], obj.get("params", {})
    if params is None:
        params = {}
    names = get_registry().names("primitive")
    if not isinstance(name, str) or name not in names:
        raise ReplyError(f"unknown primitive {json.dumps(name, default=str):.60}; the primitives are: "
                         f"{', '.join(names)}", "unknown primitive")
    problem = check_call(name, _relaxed(primitive_params(name), view), params, list(object_ids))
    if problem:
        raise ReplyError(problem, "invalid parameters")
    return ActionCall(name, dict(params))


def parse_reply(text: str | None, view: ObservationMode, object_ids: Sequence[int]) -> ActionCall | Answer | None:
    """The decision in a reply's text; ``ReplyError`` when there is none or it is not valid."""
    if not text or not text.strip():
        raise ReplyError("the reply is empty", "empty reply")
    return decision_from(first_json_object(text), view, object_ids)


def _param_schema(p: Param, view: ObservationMode, object_ids: Sequence[int]) -> dict[str, Any]:
    number: dict[str, Any] = {"type": "integer" if p.kind == "int" else "number"}
    if p.low is not None:
        number["minimum"] = p.low
    if p.high is not None:
        number["maximum"] = p.high
    pixel = {"type": "array", "items": {"type": "integer", "minimum": 0}, "minItems": 2, "maxItems": 2}
    obj = pixel if view == ObservationMode.image else ({"type": "integer", "enum": list(object_ids)} if object_ids
                                       else {"type": "integer"})
    part = {"type": "string", "enum": list(TABLE_PARTS)}
    if p.kind == "object":
        return obj
    if p.kind == "part":
        return part
    if p.kind == "place":
        return {"anyOf": [obj, part]}
    if p.kind in ("int", "number"):
        return number
    if p.kind == "vector":
        items = {k: v for k, v in number.items()}
        vector: dict[str, Any] = {"type": "array", "items": items}
        if p.length:
            vector.update(minItems=p.length, maxItems=p.length)
        return vector
    return {}


def decision_schema(view: ObservationMode, object_ids: Sequence[int]) -> dict[str, Any]:
    """The JSON schema of a valid decision in this scene: one alternative per registered primitive (its typed
    parameters, object ids limited to the scene's), an answer, or a stop."""
    actions = []
    for name in get_registry().names("primitive"):
        params = primitive_params(name)
        actions.append({"type": "object", "properties": {
            "name": {"type": "string", "enum": [name]},
            "params": {"type": "object", "properties": {p.name: _param_schema(p, view, object_ids) for p in params},
                       "required": [p.name for p in params if p.required], "additionalProperties": False}},
            "required": ["name", "params"], "additionalProperties": False})
    answer = {"type": "object", "properties": {"answer": {"type": "array", "items": {"type": "number"}}},
              "required": ["answer"], "additionalProperties": False}
    stop = {"type": "object", "properties": {STOP: {"type": "boolean", "enum": [True]}}, "required": [STOP],
            "additionalProperties": False}
    return {"anyOf": [*actions, answer, stop]}
