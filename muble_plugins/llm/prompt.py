"""What the ``llm`` agent tells the model: prompt files rendered from the instruction, the scene, the registered
primitives, the last result and a bounded history.

Prompts are data a user reads and overrides: Markdown files with ``{{field}}`` placeholders. The system prompt is
rendered once per episode from ``primitives`` (every registered primitive with its typed parameters, from the
registry, so a plugin's primitive appears without a prompt edit), ``object_form`` (how an action names an object in
this observation mode) and ``examples``; the step message after every primitive from ``instruction``, ``program``,
``scene``, ``history``, ``last_result`` and ``step``; the re-ask after an unusable reply from ``error``. A
placeholder the renderer does not know is a ``ConfigError`` naming the valid ones, so a typo in a prompt file
fails before the first request.
"""
from __future__ import annotations

import base64
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

from muble import (ActionCall, ActionResult, Answer, ConfigError, Instruction, Observation, ObservationMode,
                   PluginError, PrimitiveAction, Track, get_registry)
from muble.core.observation import MEASURED_EXTRA
from muble.core.params import Param, specs
from muble.core.types import TABLE_PARTS

PROMPTS = Path(__file__).parent / "prompts"
SYSTEM_FIELDS = ("primitives", "object_form", "examples")
STEP_FIELDS = ("instruction", "program", "scene", "history", "last_result", "step")
RETRY_FIELDS = ("error",)
PLACEHOLDER = re.compile(r"\{\{\s*([A-Za-z_]+)\s*\}\}")
FLAGS = ("in_hand", "raised", "approached", "gripper_over", "touching")
DECIMALS = 3  # positions and sizes in millimetres are as precise as the planner needs


@dataclass(frozen=True)
class PromptTemplate:
    """One prompt file and the fields it may use."""

    path: Path
    text: str
    fields: tuple[str, ...]

    @classmethod
    def load(cls, path: str | Path | None, default: str, fields: tuple[str, ...]) -> "PromptTemplate":
        """The file at ``path`` (the package's ``prompts/<default>`` when None), its placeholders checked."""
        file = Path(path).expanduser() if path else PROMPTS / default
        if not file.is_file():
            raise ConfigError(f"prompt file {file} does not exist; give the path of a Markdown file with "
                              f"{{{{field}}}} placeholders, or leave the option unset for {PROMPTS / default}")
        text = file.read_text(encoding="utf-8")
        unknown = sorted({m.group(1) for m in PLACEHOLDER.finditer(text)} - set(fields))
        if unknown:
            raise ConfigError(f"prompt file {file}: unknown placeholder(s) {unknown}; valid: "
                              f"{', '.join('{{' + f + '}}' for f in fields)}")
        return cls(file, text, fields)

    def render(self, **values: str) -> str:
        return PLACEHOLDER.sub(lambda m: str(values.get(m.group(1), "")), self.text).strip() + "\n"


# The names measured properties get in an object's JSON, where a unit belongs in the name.
MEASURED_FIELDS = {"stiffness": "stiffness_n_per_m", "com_offset": "com_offset_mm"}


def _round(values: Any) -> list[float]:
    return [round(float(v), DECIMALS) for v in values]


def object_entry(o: Any) -> dict[str, Any]:
    """One object as compact JSON: what is known of it in this view (words, pose, size, measurements, flags)."""
    entry: dict[str, Any] = {"id": o.id}
    for key in ("name", "colour", "material", "shape", "size"):
        if getattr(o, key, None) is not None:
            entry[key] = getattr(o, key)
    entry["position"] = _round(o.position)
    if isinstance(o.bbox, dict):
        entry["extent"] = _round(o.bbox[k] for k in ("x", "y", "z") if k in o.bbox)
    if o.weight is not None:
        entry["weight_g"] = round(float(o.weight), 1)
    for name, key in MEASURED_EXTRA.items():  # what the agent measured besides the weight
        value = o.extra.get(key)
        if value is not None:
            entry[MEASURED_FIELDS.get(name, name)] = (value if isinstance(value, bool) else _round(value)
                                                      if isinstance(value, (list, tuple)) else round(float(value), 3))
    flags = [f for f in FLAGS if o.extra.get(f)]
    if flags:
        entry["state"] = flags
    return entry


def scene_text(observation: Observation) -> str:
    """The scene as one compact JSON object per line (graph and masks modes), or what the images are (image)."""
    objects = list(getattr(observation.scene, "objects", []) or [])
    if not objects:
        if observation.images:
            sizes = ", ".join(f"{name} {f.rgb.shape[1]}x{f.rgb.shape[0]}" for name, f in observation.images.items())
            return f"(seen only in the images: {sizes}; name an object by a pixel [x, y] inside it)"
        return "(none observed)"
    return "\n".join(json.dumps(object_entry(o), separators=(",", ":")) for o in objects)


def image_parts(observation: Observation) -> list[dict[str, Any]]:
    """The observation's RGB images as chat content parts with PNG data URLs (for vision models)."""
    from muble.episode.runner import png_bytes

    parts: list[dict[str, Any]] = []
    for name, frame in observation.images.items():
        data = base64.b64encode(png_bytes(frame.rgb)).decode("ascii")
        parts += [{"type": "text", "text": f"Camera {name}:"},
                  {"type": "image_url", "image_url": {"url": f"data:image/png;base64,{data}"}}]
    return parts


def program_text(instruction: Instruction) -> str:
    """The symbolic program on the program track (``scene -> filter_colour(blue) -> query_weight``); nothing on
    the language track, where the agent gets the text only."""
    if not instruction.program:
        return ""
    steps = [f"{s.get('type')}({s['input_value']})" if s.get("input_value") is not None else str(s.get("type"))
             for s in instruction.program]
    return "Program: " + " -> ".join(steps) + "\n"


def _kind_text(p: Param, view: ObservationMode) -> str:
    bounds = ""
    if p.low is not None or p.high is not None:
        bounds = f" in [{p.low if p.low is not None else '-inf'}, {p.high if p.high is not None else 'inf'}]"
    obj = "pixel [x, y] inside the object" if view == ObservationMode.image else "object id"
    kind = {"object": obj, "part": f"table part ({'/'.join(TABLE_PARTS)})",
            "place": f"{obj} or table part ({'/'.join(TABLE_PARTS)})", "int": "integer", "number": "number",
            "vector": f"list of {p.length or 'some'} numbers", "any": "any value"}[p.kind]
    return f"{p.name}: {kind}{bounds}{'' if p.required else ', optional'}"


def primitive_params(name: str) -> tuple[Param, ...]:
    """The registered primitive's typed parameters."""
    factory = get_registry().get("primitive", name).record.factory
    if not (isinstance(factory, type) and issubclass(factory, PrimitiveAction)):
        raise PluginError(f"primitive {name!r} is registered with {factory!r}, not a PrimitiveAction class: it "
                          "declares no parameters")
    return specs(factory.params)


def primitives_text(view: ObservationMode) -> str:
    """Every registered primitive, one line each: name, description, parameters in this observation mode's terms."""
    registry = get_registry()
    lines = []
    for name in registry.names("primitive"):
        record = registry.get("primitive", name).record
        params = "; ".join(_kind_text(p, view) for p in primitive_params(name)) or "no parameters"
        lines.append(f"- {name}: {record.description} ({params})")
    return "\n".join(lines)


def object_form(view: ObservationMode) -> str:
    """How an action names an object in this observation mode."""
    if view == ObservationMode.image:
        return ("Objects have no ids here: name an object by a pixel [x, y] (column, row) inside it in the first "
                "camera's image.")
    if view == ObservationMode.masks:
        return "Name an object by its id; the objects' words are not given: tell them apart in the images."
    return "Name an object by its id."


def action_json(action: ActionCall) -> str:
    return json.dumps({"name": action.name, "params": action.params}, separators=(",", ":"), default=str)


def result_text(result: ActionResult | None) -> str:
    """The last primitive's result in one line: ok or failed with the reason, and any measurement."""
    if result is None:
        return "none yet"
    text = "ok" if result.success else f"failed: {result.failure_reason or 'no reason given'}"
    if result.measurement is not None:
        text += f"; measured {result.measurement}"
    return text


@dataclass
class Turn:
    """One past decision of the episode and how it went."""

    decision: ActionCall | Answer
    result: ActionResult | None = None

    def text(self) -> str:
        if isinstance(self.decision, Answer):
            return f"answered {json.dumps(self.decision.value, default=str)}"
        return f"{action_json(self.decision)} -> {result_text(self.result)}"


def history_text(turns: list[Turn], bound: int) -> str:
    """The last ``bound`` turns, numbered; older ones counted."""
    if not turns or bound == 0:
        return "none"
    shown = turns[-bound:]
    first = len(turns) - len(shown)
    lines = [f"({first} earlier steps not shown)"] if first else []
    lines += [f"{first + i + 1}. {t.text()}" for i, t in enumerate(shown)]
    return "\n".join(lines)


def examples_text(examples: Iterable[dict[str, Any]], track: Track) -> str:
    """Worked examples as text: the instruction (and program on the program track), the objects, and the
    ground-truth decisions one JSON object per line."""
    blocks = []
    for n, ex in enumerate(examples, 1):
        lines = [f"Example {n}. Instruction: {ex['instruction']}"]
        if track == Track.program and ex.get("program"):
            lines.append(program_text(Instruction(ex["instruction"], ex["program"], "", "")).strip())
        if ex.get("objects"):
            lines.append("Objects: " + "; ".join(ex["objects"]))
        lines += [json.dumps(d, separators=(",", ":")) for d in ex["decisions"]]
        blocks.append("\n".join(lines))
    return ("\nWorked examples (other scenes):\n\n" + "\n\n".join(blocks) + "\n") if blocks else ""
