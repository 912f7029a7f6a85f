"""JSON Schemas of the primitives' parameters, for the ``hello`` reply: what a remote agent may put in a call's
``params``, in a form any JSON Schema validator checks (draft 2020-12).

Each schema comes from the primitive's declared ``muble.core.params.Param`` records, the same ones the action loop
checks every call against (``check_call``), so what the schema allows and what the loop accepts cannot drift
apart. The one check a schema cannot state is that an object id names an object of the current scene: the
observation's ``scene.objects[k].id`` are the valid ones.
"""
from __future__ import annotations

from typing import Any, Iterable

from muble.core.params import Param, specs
from muble.core.types import TABLE_PARTS

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"

_OBJECT = {"type": "integer", "minimum": 0,
           "description": "the id of an object in the observed scene (observation.scene.objects[k].id)"}
_PART = {"type": "string", "enum": list(TABLE_PARTS), "description": "a table part, as seen from the scene camera"}


def param_schema(param: Param) -> dict[str, Any]:
    """The JSON Schema of one parameter's values, by its kind; ``x-muble-kind`` names the kind itself."""
    bounds = {key: value for key, value in (("minimum", param.low), ("maximum", param.high)) if value is not None}
    kind = param.kind
    if kind == "object":
        schema: dict[str, Any] = dict(_OBJECT)
    elif kind == "part":
        schema = dict(_PART)
    elif kind == "place":
        schema = {"anyOf": [dict(_OBJECT), dict(_PART)]}
    elif kind == "int":
        schema = {"type": "integer", **bounds}
    elif kind == "number":
        schema = {"type": "number", **bounds}
    elif kind == "vector":
        schema = {"type": "array", "items": {"type": "number", **bounds}}
        if param.length is not None:
            schema.update(minItems=param.length, maxItems=param.length)
    else:  # "any": the primitive takes whatever JSON value it is given
        schema = {}
    schema["x-muble-kind"] = kind
    if param.default is not None:
        schema["default"] = param.default
    if param.doc:
        schema["description"] = param.doc
    return schema


def params_schema(declared: Iterable[str | Param]) -> dict[str, Any]:
    """The JSON Schema of a call's whole ``params`` object: known names only, the required ones present."""
    params = specs(declared)
    return {"$schema": JSON_SCHEMA_DIALECT, "type": "object",
            "properties": {p.name: param_schema(p) for p in params},
            "required": [p.name for p in params if p.required], "additionalProperties": False}


def primitive_entries(registry: Any) -> list[dict[str, Any]]:
    """One ``hello`` entry per registered primitive: ``name``, ``description``, ``params`` (one line of text per
    parameter, for people) and ``parameters`` (the JSON Schema of ``params``, for programs)."""
    entries = []
    for name in registry.names("primitive"):
        record = registry.get("primitive", name).record
        declared = getattr(record.factory, "params", ())
        entries.append({"name": name, "description": record.description,
                        "params": [p.describe() for p in specs(declared)], "parameters": params_schema(declared)})
    return entries
