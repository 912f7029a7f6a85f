"""A static website of ``muble eval`` runs: a leaderboard, a page per run and a page per episode.

``build_site(folders, out)`` reads each run folder (``results.json``, ``episodes_<split>.jsonl``, ``keyframes/``,
``llm_logs/``) and writes plain HTML files that open from disk or any static file server, with one small script
for sorting and filtering tables (``site_assets/site.js``) and no server of MuBlE's:

- ``index.html``: one row per run and split (agent, track, mode, protocol, split, success with its Wilson 95%
  interval, efficiency, measurement ratio, tokens per success; the recovery rate after disturbances where a run
  had them; cost per episode and per success and latency p50/p95 per request where a run counted tokens),
  sortable and filterable;
- ``runs/<run>/<split>/index.html``: success per task type with intervals (an SVG plot), the closed-loop metrics
  of a run with disturbances, the failure taxonomy and the episodes, filterable by template and outcome;
- ``runs/<run>/<split>/<index>.html``: the instruction and (program track) its program, every decision with its
  result, failure reason and measurement, the disturbances that fired (marked on the decisions and keyframes),
  measurements beside the true values (read from the scene file when the site is built, never shown to an agent),
  the keyframes as a strip and a GIF, the LLM's dialogue for ``agent=llm``, and links to the same episode in every
  other run on the same data.

Images are files the pages reference (keyframes hard-linked or copied from the run, a GIF made from them), so a
page of a 1,000-episode run stays small.
"""
from __future__ import annotations

import html
import json
import os
import re
import shutil
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError
from muble.evaluation.closed_loop import detection_delay, parse_action
from muble.evaluation.report import partial_words
from muble.evaluation.usage import (INPUT_TOKENS, OUTPUT_TOKENS, PriceTable, dollars, prices_text, seconds_p50_p95,
                                    usage_summary)

ASSETS = Path(__file__).with_name("site_assets")
RECORDS = "episodes_{split}.jsonl"
LLM_LOGS = "llm_logs"
def measured_properties() -> dict[str, tuple[str, str]]:
    """Registered primitive name -> (the property it measures, its unit): the registry says which primitives
    measure (``PrimitiveAction.measures``, ``measure_unit``)."""
    from muble.plugins.registry import get_registry

    registry = get_registry()
    out = {}
    for name in registry.names("primitive"):
        factory = registry.get("primitive", name).record.factory
        prop = getattr(factory, "measures", None)
        if prop:
            out[name] = (str(prop), str(getattr(factory, "measure_unit", "") or ""))
    return out


@dataclass
class Run:
    """One ``muble eval`` output folder as the site shows it."""

    folder: Path
    slug: str
    results: dict[str, Any]
    records: dict[str, list[dict[str, Any]]] = field(default_factory=dict)  # split -> records in index order

    @property
    def label(self) -> str:
        r = self.results
        return f"{r.get('agent')} ({r.get('track')}, {r.get('mode')})"

    def pair_key(self, split: str) -> tuple:
        """Runs with the same key ran the same episodes (the same data under the same split name)."""
        r = self.results
        return (r.get("protocol"), split, r.get("data_sha256"))


def _slug(text: str, taken: set[str]) -> str:
    base = re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-.") or "run"
    slug, n = base, 1
    while slug in taken:
        n += 1
        slug = f"{base}-{n}"
    taken.add(slug)
    return slug


def load_run(folder: Path, slug: str) -> Run:
    from muble.evaluation.results import read_results

    results = read_results(folder)
    run = Run(Path(folder), slug, results)
    for split, entry in results["splits"].items():
        by_index = {e["index"]: dict(e) for e in entry["episodes"]}
        path = Path(folder) / RECORDS.format(split=split)
        if path.is_file():  # the full records: instruction, decisions, keyframes (results.json keeps a summary)
            for line in path.read_text(encoding="utf-8").splitlines():
                try:
                    record = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a line cut short by a kill: the summary in results.json stands
                if isinstance(record, dict) and record.get("index") in by_index:
                    by_index[record["index"]].update(record)
        run.records[split] = [by_index[i] for i in sorted(by_index)]
    return run


# --- formatting ------------------------------------------------------------------------------------------------
def pct(value: float | None) -> str:
    return "–" if value is None else f"{100 * value:.1f}%"


def interval(ci: list[float] | None) -> str:
    return "–" if not ci else f"[{100 * ci[0]:.1f}%, {100 * ci[1]:.1f}%]"


def number(value: Any, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, (list, tuple)):  # a vector reading ([x, y] mm): each number as one is shown
        return "[" + ", ".join(number(float(v) if isinstance(v, int) and not isinstance(v, bool) else v, digits)
                               for v in value) + "]"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return html.escape(str(value))


def success_svg(rows: list[tuple[str, dict[str, Any]]], width: int = 700) -> str:
    """Success rate per task type as points with their 95% intervals, drawn as SVG."""
    bar_h, left, right = 22, 250, 20
    height = bar_h * len(rows) + 40
    plot_w = width - left - right
    x = lambda v: left + plot_w * max(0.0, min(1.0, v))  # noqa: E731
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" role="img" '
             f'aria-label="success rate per task type with 95% intervals" class="plot">']
    for tick in (0, 0.25, 0.5, 0.75, 1.0):
        parts.append(f'<line x1="{x(tick):.1f}" y1="10" x2="{x(tick):.1f}" y2="{height - 25}" class="grid"/>'
                     f'<text x="{x(tick):.1f}" y="{height - 8}" text-anchor="middle">{int(tick * 100)}%</text>')
    for i, (name, s) in enumerate(rows):
        y = 20 + i * bar_h
        lo, hi = (s.get("ci") or [s.get("rate") or 0, s.get("rate") or 0])
        parts.append(f'<text x="{left - 8}" y="{y + 4}" text-anchor="end">{html.escape(name)} (n={s["episodes"]})'
                     f'</text><line x1="{x(lo):.1f}" y1="{y}" x2="{x(hi):.1f}" y2="{y}" class="ci"/>'
                     f'<circle cx="{x(s.get("rate") or 0):.1f}" cy="{y}" r="4" class="rate"><title>'
                     f'{html.escape(name)}: {s["successes"]}/{s["episodes"]} {interval(s.get("ci"))}</title></circle>')
    parts.append("</svg>")
    return "".join(parts)


# --- ground truth for the episode pages --------------------------------------------------------------------------
class Truth:
    """Scene files for measured-against-true values, read when the site is built: a protocol's shipped files, or
    the run's dataset folder where it is on this machine."""

    def __init__(self) -> None:
        self._shipped: dict[tuple[str, str], dict[str, bytes] | None] = {}

    def file(self, run: Run, split: str, rel: str) -> dict[str, Any] | None:
        """The JSON file ``rel`` (``<split>/scenes/…``) of the run's data: shipped, or in its dataset folder."""
        protocol = run.results.get("protocol")
        if protocol:
            key = (protocol, run.results.get("protocol_split") or split)
            if key not in self._shipped:
                self._shipped[key] = self._load_shipped(*key)
            files = self._shipped[key]
            if files and rel in files:
                return json.loads(files[rel])
        dataset = run.results.get("dataset")
        if dataset and " + " not in str(dataset):
            path = Path(dataset) / rel
            if path.is_file():
                try:
                    return json.loads(path.read_text(encoding="utf-8"))
                except (OSError, ValueError):
                    return None
        return None

    def scene(self, run: Run, split: str, index: int) -> dict[str, Any] | None:
        from muble.io.layout import DatasetLayout

        return self.file(run, split, f"{split}/{DatasetLayout(Path('.'), split).scene(index)}")

    def program(self, run: Run, split: str, index: int) -> list[dict[str, Any]] | None:
        """The program the agent was given on the program track (each step's type and words); None on the
        language track or where the instruction file cannot be found."""
        from muble.io.layout import DatasetLayout

        if run.results.get("track") != "program":
            return None
        record = self.file(run, split, f"{split}/{DatasetLayout(Path('.'), split).instruction(index)}")
        if not record:
            return None
        steps = []
        for step in record.get("program") or []:
            if isinstance(step, dict):
                words = step.get("input_value") or step.get("value_inputs") or []
                steps.append({"type": step.get("type") or step.get("function"),
                              "words": [words] if isinstance(words, str) else [str(w) for w in words]})
        return steps

    @staticmethod
    def _load_shipped(protocol: str, split: str) -> dict[str, bytes] | None:
        from muble.dataset.protocol import load_protocol, shipped_archive, shipped_files

        try:
            spec = load_protocol(protocol)
            return shipped_files(spec, split) if shipped_archive(spec, split) is not None else None
        except ConfigError:
            return None


def measured_against_truth(steps: list[dict[str, Any]], scene: dict[str, Any] | None,
                           measures: dict[str, tuple[str, str]]) -> list[dict[str, Any]]:
    """One row per measuring step (``measures``: ``measured_properties()``): what was measured, of which object,
    and the scene file's true value."""
    rows = []
    objects = {o.get("id", i): o for i, o in enumerate((scene or {}).get("objects") or [])}
    for step in steps:
        name, args = parse_action(step.get("action", ""))
        if name not in measures or step.get("measurement") is None:
            continue
        label, unit = measures[name]
        target = args.get("target", step.get("held"))  # without a target: the object in the hand
        index = int(target) if target is not None and str(target).lstrip("-").isdigit() else None
        obj = objects.get(index) if index is not None else None
        true = true_reading(label, obj, index) if obj and index is not None else None
        measured = step["measurement"]
        error, error_text = reading_error(measured, true, unit)
        rows.append({"action": step["action"], "what": label, "unit": unit, "measured": measured, "true": true,
                     "error": error, "error_text": error_text})
    return rows


def true_reading(label: str, obj: dict[str, Any], index: int = 0) -> Any:
    """The scene file object's true value of the property ``label`` as the measuring primitive reports it (its
    unit and shape: a centre of mass [x, y] mm, never the file's metres; ``Quantity.reading_truth``); for a
    property no quantity names (a plugin's), the file's ``<property>_gt`` field, else the field of its name."""
    from muble.io.scene_io import object_from_dict
    from muble.programs.program import QUANTITIES

    if label not in QUANTITIES:
        return obj.get(f"{label}_gt", obj.get(label))
    try:
        return QUANTITIES[label].reading_truth(object_from_dict(obj, index))
    except (ConfigError, ValueError, TypeError, KeyError):  # a file the site cannot read: no true value
        return None


def reading_error(measured: Any, true: Any, unit: str) -> tuple[float | None, str | None]:
    """How far a measurement is from the true value, as a number and as the page shows it: a vector reading (a
    centre of mass) by the distance between the two, in the reading's unit (``1.3 mm``); a yes/no one right or
    wrong; a number relatively (``+2.1%``); (None, None) where there is nothing to compare."""
    def numbers(value: Any) -> list[float] | None:
        if isinstance(value, (list, tuple)) and value and all(isinstance(v, (int, float)) and not isinstance(
                v, bool) for v in value):
            return [float(v) for v in value]
        return None

    if isinstance(measured, bool) or isinstance(true, bool):
        if measured is None or true is None:
            return None, None
        return float(bool(measured) != bool(true)), "right" if bool(measured) == bool(true) else "wrong"
    got, want = numbers(measured), numbers(true)
    if got is not None and want is not None and len(got) == len(want):
        distance = sum((a - b) ** 2 for a, b in zip(got, want)) ** 0.5
        return distance, f"{distance:.3g} {unit}".strip()
    if isinstance(measured, (int, float)) and isinstance(true, (int, float)) and true:
        relative = (measured - true) / true
        return relative, f"{100 * relative:+.1f}%"
    return None, None


# --- disturbances ------------------------------------------------------------------------------------------------
def disturbance_rows(record: dict[str, Any], frames: list[str]) -> list[dict[str, Any]]:
    """The episode's disturbances as its page lists them: each event of the record with the primitive it fired
    during or right after (``step``, 1-based, and its text), its detection delay (None: never addressed) and the
    keyframes before and after that primitive (``frames[step - 1]`` and ``frames[step]``: the first keyframe is the
    scene before any primitive), where every keyframe of the record is on the page."""
    events = record.get("disturbances") or []
    if not events:
        return []
    from muble.evaluation.episodes import measuring_primitives

    primitives = record.get("primitives") or [s.get("action", "") for s in record.get("steps") or []]
    measuring = measuring_primitives()
    aligned = len(frames) == len(record.get("keyframes") or []) > 0
    rows = []
    for n, event in enumerate(events, 1):
        step = int(event.get("step", 0))
        rows.append({**event, "id": f"disturbance-{n}", "step": step,
                     "primitive": primitives[step - 1] if 0 < step <= len(primitives) else None,
                     "delay": detection_delay(event, primitives, measuring),
                     "before": frames[step - 1] if aligned and 0 < step <= len(frames) else None,
                     "after": frames[step] if aligned and 0 <= step < len(frames) else None})
    return rows


# --- LLM dialogues ------------------------------------------------------------------------------------------------
def dialogue(run: Run, split: str, index: int, template: str) -> list[dict[str, Any]]:
    """The LLM agent's log of one episode as entries to show: requests (their messages' text; images as a note),
    replies, unusable replies with why, errors and decisions. Empty without a log."""
    folder = run.folder / LLM_LOGS
    if not folder.is_dir():
        return []
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", f"{split}_{index:06d}_{template}")
    path = folder / f"{stem}.jsonl"
    if not path.is_file():
        return []
    entries = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            continue
        kind = entry.get("kind")
        if kind == "request":
            messages = []
            for m in (entry.get("body") or {}).get("messages") or []:
                content = m.get("content")
                texts, images = [], 0
                for part in content if isinstance(content, list) else [content]:
                    if isinstance(part, dict) and part.get("type") == "image_url":
                        images += 1
                    elif isinstance(part, dict):
                        texts.append(str(part.get("text", "")))
                    elif part is not None:
                        texts.append(str(part))
                messages.append({"role": m.get("role"), "text": "\n".join(texts), "images": images})
            entries.append({"kind": "request", "messages": messages})
        elif kind in ("reply", "unusable", "error", "decision", "episode"):
            entries.append({k: v for k, v in entry.items() if k not in ("time", "schema", "view")})
    return entries


# --- building ---------------------------------------------------------------------------------------------------
def _environment():
    import jinja2

    # Records of older runs lack some fields (steps, instruction): a missing one renders empty.
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(ASSETS)), autoescape=True,
                             undefined=jinja2.ChainableUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters.update(pct=pct, interval=interval, number=number, dollars=dollars, p50_p95=seconds_p50_p95)
    env.filters["partial"] = partial_words  # a run of a split's first N episodes says so wherever it is shown
    return env


def _link_or_copy(src: Path, dest: Path) -> None:
    dest.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(src, dest)
    except OSError:
        shutil.copyfile(src, dest)


def _keyframes(run: Run, record: dict[str, Any], page_dir: Path, stem: str) -> tuple[list[str], str | None]:
    """The episode's keyframes placed beside its page (relative names) and a GIF of them (None without frames)."""
    frames = []
    for i, name in enumerate(record.get("keyframes") or []):
        src = Path(name)
        if not src.is_absolute():
            src = run.folder / src
        if not src.is_file():  # a run folder moved since: look in its own keyframes/ folder
            src = run.folder / "keyframes" / Path(name).parent.name / Path(name).name
        if src.is_file():
            rel = f"{stem}/{i:04d}{src.suffix}"
            _link_or_copy(src, page_dir / rel)
            frames.append(rel)
    gif = None
    if len(frames) > 1:
        from PIL import Image

        # One palette for every frame, from the first by fast octree quantisation (median cut, PIL's default for
        # GIFs, costs most of a large site's build); the scene changes little between keyframes.
        first = Image.open(page_dir / frames[0]).convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE)
        images = [first] + [Image.open(page_dir / f).convert("RGB").quantize(palette=first, dither=Image.Dither.NONE)
                            for f in frames[1:]]
        gif = f"{stem}/episode.gif"
        images[0].save(page_dir / gif, save_all=True, append_images=images[1:], duration=800, loop=0)
    return frames, gif


def build_site(folders: list[str | Path], out: str | Path) -> dict[str, Any]:
    """Write the site of the runs in ``folders`` into ``out`` (atomically: the whole site or nothing). Returns
    counts (runs, episode pages)."""
    from muble.io.atomic import check_output_folder, staged_folder

    if not folders:
        raise ConfigError("name at least one run folder (the output folder of a `muble eval` run)")
    out = check_output_folder(Path(out), "--out")
    taken: set[str] = set()
    runs = [load_run(Path(f), _slug(Path(f).name, taken)) for f in folders]
    for run in runs:
        if run.folder.resolve() == out.resolve():
            raise ConfigError(f"--out {out} is one of the runs; pass another folder for the site")
    env = _environment()
    truth = Truth()
    pairs: dict[tuple, list[tuple[Run, str]]] = {}
    for run in runs:
        for split in run.records:
            pairs.setdefault(run.pair_key(split), []).append((run, split))
    pages = 0
    with staged_folder(out, "--out", replace=True) as stage:
        for asset in ("site.css", "site.js"):
            shutil.copyfile(ASSETS / asset, stage / asset)
        board = []
        for run in runs:
            for split, records in run.records.items():
                summary = run.results["splits"][split]["summary"]
                overall = summary["overall"]
                usage = usage_summary(records)
                successes = overall["successes"]
                tokens = usage[INPUT_TOKENS] + usage[OUTPUT_TOKENS] if usage else 0
                board.append({"run": run, "split": split, "overall": overall, "href": f"runs/{run.slug}/{split}/",
                              "tokens_per_success": tokens / successes if successes and tokens else None,
                              "closed_loop": overall.get("closed_loop"), "usage": usage,
                              "partial": run.results["splits"][split].get("partial")})
                pages += _write_run(env, stage, run, split, records, summary, pairs, truth)
        (stage / "index.html").write_text(env.get_template("index.html").render(
            board=board, runs=runs, root="", closed_loop=any(row["closed_loop"] for row in board),
            usage=any(row["usage"] for row in board)), encoding="utf-8")
    return {"runs": len(runs), "episodes": pages}


def _write_run(env, stage: Path, run: Run, split: str, records: list[dict[str, Any]], summary: dict[str, Any],
               pairs: dict[tuple, list[tuple[Run, str]]], truth: Truth) -> int:
    from muble.io.layout import DatasetLayout

    folder = stage / "runs" / run.slug / split
    folder.mkdir(parents=True, exist_ok=True)
    outcomes = Counter(r["outcome"] for r in records)
    failures = failure_taxonomy(records)
    templates = [(name, s) for name, s in summary["templates"].items()]
    others = [(o, s) for o, s in pairs.get(run.pair_key(split), []) if o is not run]
    indices = {(o.slug, s): {r["index"] for r in o.records[s]} for o, s in others}
    layout = DatasetLayout(Path("."), split)
    measures = measured_properties()
    price_table = PriceTable.of(run.results.get("agent_config"))
    for i, record in enumerate(records):
        index = record["index"]
        stem = layout.stem(index)
        frames, gif = _keyframes(run, record, folder, stem)
        steps = record.get("steps") or [{"action": a, "success": None, "measurement": None, "failure_reason": None}
                                        for a in record.get("primitives") or []]
        scene = truth.scene(run, split, index)
        page = env.get_template("episode.html").render(
            root="../../../", run=run, split=split, record=record, steps=steps, frames=frames, gif=gif,
            disturbances=disturbance_rows(record, frames),
            truth=measured_against_truth(steps, scene, measures), program=truth.program(run, split, index),
            dialogue=dialogue(run, split, index, record.get("template", "")),
            same=[(o, s, f"../../../runs/{o.slug}/{s}/{index:06d}.html") for o, s in others
                  if index in indices[(o.slug, s)]],
            previous=f"{records[i - 1]['index']:06d}.html" if i else None,
            next=f"{records[i + 1]['index']:06d}.html" if i + 1 < len(records) else None)
        (folder / f"{index:06d}.html").write_text(page, encoding="utf-8")
    (folder / "index.html").write_text(env.get_template("run.html").render(
        root="../../../", run=run, split=split, records=records, summary=summary, templates=templates,
        usage=usage_summary(records), prices=prices_text(price_table.as_dict() if price_table else None),
        plot=success_svg(
            templates + [("overall", summary["overall"])]), outcomes=outcomes.most_common(), failures=failures,
        others=others, template_names=sorted({r.get("template", "") for r in records}),
        outcome_names=sorted(outcomes)), encoding="utf-8")
    return len(records)


def failure_taxonomy(records: list[dict[str, Any]]) -> dict[str, Counter]:
    """Per failure class (an episode's outcome other than success), how often each cause ended it: the record's
    error, else its last failed decision's reason, with ids and numbers taken out (``reason_class``)."""
    failures: dict[str, Counter] = {}
    for r in records:
        if r["outcome"] != "success":
            reason = r.get("error") or next((s.get("failure_reason") for s in reversed(r.get("steps") or [])
                                             if s.get("failure_reason")), None) or NO_REASON
            failures.setdefault(r["outcome"], Counter())[reason_class(reason)] += 1
    return failures


NO_REASON = "(no failed decision: the final state or answer is wrong)"


def reason_class(reason: str) -> str:
    """A failure reason with object ids, numbers and quoted names taken out, so like reasons count together."""
    text = re.sub(r"\d+(\.\d+)?", "N", str(reason))
    text = re.sub(r"'[^']*'", "'…'", text)
    return text[:160]

