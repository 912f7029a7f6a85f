"""From per-episode records to the benchmark's results: success per task type, failure taxonomy, timing.

Everything here is a pure function of the records (sorted by index), so the same episodes give the same report
whichever executor or worker count produced them; wall-time figures are kept in their own ``timing`` block.
"""
from __future__ import annotations

from collections import Counter
from typing import Any, Iterable

from muble.core.types import Outcome

OVERALL = "overall"
OUTCOMES = [o.value for o in Outcome]
# The data's fault: entries listed one by one in the report, by file.
BAD_DATA = (Outcome.INVALID_DATA.value, Outcome.BROKEN_SCENE.value)
# The template row of episodes whose instruction file cannot be read or names no registered template.
UNKNOWN = "unknown"


def _rate(successes: int, episodes: int) -> float:
    return successes / episodes if episodes else 0.0


def summarize(records: Iterable[dict[str, Any]], templates: list[str] | None = None) -> dict[str, Any]:
    """Success rate per template and overall, outcome counts (all taxonomy classes, zeros included), timing.

    ``templates`` fixes the row order (the configured template mix); templates met only in the records follow, and
    the ``unknown`` row (entries whose instruction could not be read) comes last. Entries with bad data count in
    every denominator and are listed in ``bad_entries`` (index, file, outcome, error).
    """
    records = sorted(records, key=lambda r: r["index"])
    seen = [r["template"] for r in records]
    extra = sorted(set(seen) - set(templates or []) - {UNKNOWN})
    order = [t for t in (templates or []) if t in seen] + extra + ([UNKNOWN] if UNKNOWN in seen else [])
    rows = {}
    for template in order:
        rs = [r for r in records if r["template"] == template]
        counts = Counter(r["outcome"] for r in rs)
        rows[template] = {"episodes": len(rs), "successes": counts[Outcome.SUCCESS.value],
                          "success_rate": _rate(counts[Outcome.SUCCESS.value], len(rs)),
                          "outcomes": {o: counts[o] for o in OUTCOMES}}
    counts = Counter(r["outcome"] for r in records)
    overall = {"episodes": len(records), "successes": counts[Outcome.SUCCESS.value],
               "success_rate": _rate(counts[Outcome.SUCCESS.value], len(records)),
               "outcomes": {o: counts[o] for o in OUTCOMES}}
    timed = [r["timing"] for r in records if r.get("timing")]
    timing = {part: sum(t[part] for t in timed) for part in ("physics", "planning", "rendering", "total")}
    timing["episodes"] = len(timed)
    timing["episodes_per_hour_per_worker"] = 3600.0 * len(timed) / timing["total"] if timing["total"] else None
    primitives = [len(r["primitives"]) for r in records]
    bad = [{"index": r["index"], "file": r.get("file"), "template": r["template"], "outcome": r["outcome"],
            "error": r.get("error")} for r in records if r["outcome"] in BAD_DATA]
    return {"templates": rows, OVERALL: overall, "failures": {o: n for o, n in overall["outcomes"].items()
                                                             if o != Outcome.SUCCESS.value},
            "mean_primitives": sum(primitives) / len(primitives) if primitives else 0.0, "timing": timing,
            "bad_entries": bad}


def success_table(summary: dict[str, Any], title: str = "") -> str:
    """The results table: one row per task type and an overall row (success rate in percent)."""
    rows = [(t, s["episodes"], s["successes"], s["success_rate"]) for t, s in summary["templates"].items()]
    o = summary[OVERALL]
    rows.append((OVERALL, o["episodes"], o["successes"], o["success_rate"]))
    width = max(len("task type"), *(len(r[0]) for r in rows))
    lines = [title] if title else []
    lines.append(f"{'task type'.ljust(width)}  episodes  successes  success rate")
    lines.append(f"{'-' * width}  --------  ---------  ------------")
    for i, (name, n, k, rate) in enumerate(rows):
        if i == len(rows) - 1:
            lines.append(f"{'-' * width}  --------  ---------  ------------")
        lines.append(f"{name.ljust(width)}  {n:8d}  {k:9d}  {100 * rate:11.1f}%")
    return "\n".join(lines)


def failure_table(summary: dict[str, Any]) -> str:
    counts = summary["failures"]
    width = max(len(o) for o in counts)
    return "\n".join(["failure class".ljust(width) + "  episodes"]
                     + [f"{o.ljust(width)}  {n:8d}" for o, n in counts.items()])


def _one_line(text: Any, width: int | None = None) -> str:
    line = " ".join(str(text or "").split())
    return line if width is None or len(line) <= width else line[:width - 1] + "…"


def bad_entry_table(summary: dict[str, Any], error_width: int = 100) -> str:
    """The entries with bad data, one line each: file, outcome and error (empty when there are none)."""
    bad = summary.get("bad_entries", [])
    if not bad:
        return ""
    files = [e["file"] or f"index {e['index']}" for e in bad]
    width = max(len("bad entry"), *(len(f) for f in files))
    outcome_width = max(len("outcome"), *(len(e["outcome"]) for e in bad))
    lines = [f"{'bad entry'.ljust(width)}  {'outcome'.ljust(outcome_width)}  error"]
    lines += [f"{f.ljust(width)}  {e['outcome'].ljust(outcome_width)}  {_one_line(e['error'], error_width)}"
              for f, e in zip(files, bad)]
    return "\n".join(lines)


def markdown(report: dict[str, Any], plots: dict[str, str]) -> str:
    """A Markdown summary of a report: per split, the success table, the failure taxonomy, timing and plot."""
    lines = [f"# Evaluation of agent `{report['agent']}`", "",
             f"Dataset `{report['dataset']}`; seeds and versions in `report.json`.", ""]
    for split, summary in report["splits"].items():
        lines += [f"## Split `{split}`", "", "| task type | episodes | successes | success rate |",
                  "|---|---:|---:|---:|"]
        for t, s in summary["templates"].items():
            lines.append(f"| {t} | {s['episodes']} | {s['successes']} | {100 * s['success_rate']:.1f}% |")
        o = summary[OVERALL]
        lines += [f"| **{OVERALL}** | **{o['episodes']}** | **{o['successes']}** | "
                  f"**{100 * o['success_rate']:.1f}%** |", "", "| failure class | episodes |", "|---|---:|"]
        lines += [f"| {c} | {n} |" for c, n in summary["failures"].items()]
        if summary.get("skipped"):
            lines += ["", f"{len(summary['skipped'])} indices skipped: no template of the mix applied to their scene."]
        bad = summary.get("bad_entries", [])
        if bad:
            lines += ["", f"Entries with bad data ({len(bad)}; counted in the rates above):", "",
                      "| file | outcome | error |", "|---|---|---|"]
            for e in bad:
                error = _one_line(e["error"]).replace("|", r"\|")
                lines.append(f"| `{e['file'] or e['index']}` | {e['outcome']} | {error} |")
        t = summary["timing"]
        if t["total"]:
            lines += ["", f"Time per episode: {t['total'] / t['episodes']:.1f} s (physics "
                      f"{t['physics'] / t['episodes']:.1f} s, planning {t['planning'] / t['episodes']:.1f} s, "
                      f"rendering {t['rendering'] / t['episodes']:.1f} s); "
                      f"{t['episodes_per_hour_per_worker']:.0f} episodes per hour per worker."]
        if split in plots:
            lines += ["", f"![success rate per task type, split {split}]({plots[split]})"]
        lines.append("")
    return "\n".join(lines)
