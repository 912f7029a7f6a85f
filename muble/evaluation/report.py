"""From per-episode records to the benchmark's results: success per task type with its 95% interval, efficiency,
failure taxonomy, timing.

Everything here is a pure function of the records (sorted by index), so the same episodes give the same report
whichever executor or worker count produced them; wall-time figures are kept in their own ``timing`` block.

Efficiency is told beside success in two numbers. ``spl`` (success weighted by primitive count, after the "success
weighted by path length" of navigation benchmarks) is the mean over episodes with a ground-truth plan of
``success * gt / max(gt, used)``: 1 for an agent that always succeeds with no more primitives than the oracle's
plan, less for detours, 0 for failures. ``measurement_ratio`` is the measurements (weighing, squeezing, pushing …) an
agent made, the measuring primitives that succeeded (a failed one read nothing), over those the ground-truth plans
needed: above 1 it measures more than the task asks, below 1 it guesses.

An agent that counts its own costs (``stats()``, e.g. tokens and requests of a model behind an endpoint) has them
summed per task type and overall in ``agent_stats`` (``agent_totals``), with two figures derived from the usual
names: tokens per success (input and output tokens, ``muble.evaluation.usage``'s OpenTelemetry names, over the
successes) and the parse-failure rate (``parse_failures`` over ``replies``); where the records have token counters,
a ``usage`` block adds cost per episode, per success and of the run, and latency p50/p95 per request
(``muble.evaluation.usage.usage_summary``).

A run with disturbances has its closed-loop metrics (``muble.evaluation.closed_loop``: recovery, detection delay,
extra primitives) in a ``closed_loop`` block of each row and in tables after the success table; a run without has
neither, and its report is what it was before disturbances existed.
"""
from __future__ import annotations

from collections import Counter
from typing import Any, Iterable

from muble.core.types import Outcome
from muble.evaluation.closed_loop import closed_loop
from muble.evaluation.stats import wilson
from muble.evaluation.usage import (COST_HEADER, INPUT_TOKENS, OUTPUT_TOKENS, current_names, prices_text,
                                    usage_cells, usage_summary)

OVERALL = "overall"
OUTCOMES = [o.value for o in Outcome]
# The data's fault: entries listed one by one in the report, by file.
BAD_DATA = (Outcome.INVALID_DATA.value, Outcome.BROKEN_SCENE.value)
# The template row of episodes whose instruction file cannot be read or names no registered template.
UNKNOWN = "unknown"


def _rate(successes: int, episodes: int) -> float:
    return successes / episodes if episodes else 0.0


def spl(records: list[dict[str, Any]]) -> float | None:
    """Success weighted by primitive count over the records with a ground-truth plan; None when none has one."""
    planned = [r for r in records if r.get("ground_truth_primitives", 0) > 0]
    if not planned:
        return None
    return sum((r["outcome"] == Outcome.SUCCESS.value) * r["ground_truth_primitives"]
               / max(r["ground_truth_primitives"], len(r["primitives"])) for r in planned) / len(planned)


def measurement_ratio(records: list[dict[str, Any]]) -> float | None:
    """Measurements made over measurements the ground-truth plans needed; None when none was needed. Records
    written before measurements were counted are left out of both sums."""
    counted = [r for r in records if "measurements" in r and "ground_truth_measurements" in r]
    needed = sum(r["ground_truth_measurements"] for r in counted)
    return sum(r["measurements"] for r in counted) / needed if needed else None


def agent_totals(records: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The agent's counters (``agent_stats`` of each record) summed and per episode, with tokens per success and
    the parse-failure rate where the counters have those names, and ``usage`` (cost and latency) where they have
    token counters; None when no record has counters."""
    counted = [r for r in records if r.get("agent_stats")]
    if not counted:
        return None
    totals: dict[str, float] = {}
    for r in counted:
        for key, value in current_names(r["agent_stats"]).items():
            totals[key] = totals.get(key, 0.0) + float(value)
    successes = sum(r["outcome"] == Outcome.SUCCESS.value for r in counted)
    tokens = totals.get(INPUT_TOKENS, 0.0) + totals.get(OUTPUT_TOKENS, 0.0)
    replies = totals.get("replies", 0.0)
    usage = usage_summary(counted)
    return {"episodes": len(counted), "totals": totals,
            "per_episode": {k: v / len(counted) for k, v in totals.items()},
            "tokens_per_success": tokens / successes if successes and INPUT_TOKENS in totals else None,
            "parse_failure_rate": totals["parse_failures"] / replies if replies and "parse_failures" in totals
            else None, **({"usage": usage} if usage else {})}


def _row(records: list[dict[str, Any]]) -> dict[str, Any]:
    """One row of the results table: counts, rate with its Wilson 95% interval, efficiency, outcome counts, and
    ``closed_loop`` (``muble.evaluation.closed_loop.closed_loop``) only where a record comes from a run with
    disturbances."""
    counts = Counter(r["outcome"] for r in records)
    successes = counts[Outcome.SUCCESS.value]
    low, high = wilson(successes, len(records))
    row = {"episodes": len(records), "successes": successes, "success_rate": _rate(successes, len(records)),
           "ci_low": low, "ci_high": high, "spl": spl(records), "measurement_ratio": measurement_ratio(records),
           "outcomes": {o: counts[o] for o in OUTCOMES}}
    closed = closed_loop(records)
    if closed is not None:
        row["closed_loop"] = closed
    return row


def summarize(records: Iterable[dict[str, Any]], templates: list[str] | None = None) -> dict[str, Any]:
    """Success rate with its 95% interval, efficiency and outcome counts (all taxonomy classes, zeros included)
    per template and overall; timing.

    ``templates`` fixes the row order (the configured template mix); templates met only in the records follow, and
    the ``unknown`` row (entries whose instruction could not be read) comes last. Entries with bad data count in
    every denominator and are listed in ``bad_entries`` (index, file, outcome, error).
    """
    records = sorted(records, key=lambda r: r["index"])
    seen = [r["template"] for r in records]
    extra = sorted(set(seen) - set(templates or []) - {UNKNOWN})
    order = [t for t in (templates or []) if t in seen] + extra + ([UNKNOWN] if UNKNOWN in seen else [])
    rows = {template: _row([r for r in records if r["template"] == template]) for template in order}
    overall = _row(records)
    timed = [r["timing"] for r in records if r.get("timing")]
    timing = {part: sum(t[part] for t in timed) for part in ("physics", "planning", "rendering", "total")}
    timing["episodes"] = len(timed)
    timing["episodes_per_hour_per_worker"] = 3600.0 * len(timed) / timing["total"] if timing["total"] else None
    primitives = [len(r["primitives"]) for r in records]
    bad = [{"index": r["index"], "file": r.get("file"), "template": r["template"], "outcome": r["outcome"],
            "error": r.get("error")} for r in records if r["outcome"] in BAD_DATA]
    agent = agent_totals(records)
    return {"templates": rows, OVERALL: overall, "failures": {o: n for o, n in overall["outcomes"].items()
                                                             if o != Outcome.SUCCESS.value},
            "mean_primitives": sum(primitives) / len(primitives) if primitives else 0.0, "timing": timing,
            "bad_entries": bad,
            "agent_stats": None if agent is None else
            {"templates": {t: agent_totals([r for r in records if r["template"] == t]) for t in order},
             OVERALL: agent}}


def run_stamp(protocol: str | None, track: str, mode: str) -> str:
    """What a run followed, for titles: ``protocol shopvrb2_v1, track program, mode graph``."""
    return f"protocol {protocol or 'none'}, track {track}, mode {mode}"


def percent_interval(low: float, high: float) -> str:
    """``[12.3%, 45.6%]``."""
    return f"[{100 * low:.1f}%, {100 * high:.1f}%]"


def _ratio(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def text_table(header: list[str], rows: list[list[str]], rule_before_last: bool = True) -> list[str]:
    """Lines of a plain-text table: the first column left-aligned, the others right-aligned, a rule under the
    header and (``rule_before_last``) above the last row, the overall one."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]

    def line(cells: list[str]) -> str:
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))).rstrip()

    rule = "  ".join("-" * w for w in widths)
    body = [line(r) for r in rows]
    if rule_before_last and len(body) > 1:
        body.insert(len(body) - 1, rule)
    return [line(header), rule, *body]


def markdown_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """Lines of a Markdown table, numbers right-aligned; a last row named ``overall`` in bold."""
    out = ["| " + " | ".join(header) + " |", "|---|" + "---:|" * (len(header) - 1)]
    for i, row in enumerate(rows):
        cells = [c.replace("|", r"\|") for c in row]
        if i == len(rows) - 1 and row[0] == OVERALL:
            cells = [f"**{c}**" for c in cells]
        out.append("| " + " | ".join(cells) + " |")
    return out


def _percent(rate: float | None) -> str:
    return "-" if rate is None else f"{100 * rate:.1f}%"


def _closed_loop_rows(summary: dict[str, Any]) -> tuple[list[str], list[list[str]]] | None:
    """The closed-loop table: per task type with disturbance records and overall, the disturbed and recovered
    episodes, the recovery rate with its interval, fired over planned disturbances, the mean detection delay, the
    events never addressed and the mean extra primitives; None for a run without disturbances."""
    if not summary[OVERALL].get("closed_loop"):
        return None
    groups = [(t, s["closed_loop"]) for t, s in summary["templates"].items() if s.get("closed_loop")]
    rows = [[name, str(c["disturbed"]), str(c["recovered"]), _percent(c["recovery_rate"]),
             percent_interval(c["ci_low"], c["ci_high"]), f"{c['disturbances_fired']}/{c['disturbances_planned']}",
             _ratio(c["detection_delay"]), str(c["unaddressed"]), _ratio(c["extra_primitives"])]
            for name, c in [*groups, (OVERALL, summary[OVERALL]["closed_loop"])]]
    return ["task type", "disturbed", "recovered", "recovery rate", "95% CI", "fired/planned", "detection delay",
            "unaddressed", "extra primitives"], rows


def _kind_rows(summary: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Recovery per disturbance kind, overall: episodes it fired in, successes among them, rate and interval."""
    kinds = summary[OVERALL]["closed_loop"]["recovery_by_kind"]
    rows = [[kind, str(k["episodes"]), str(k["successes"]), _percent(k["rate"]),
             percent_interval(k["ci_low"], k["ci_high"])] for kind, k in kinds.items()]
    return ["disturbance kind", "episodes", "recovered", "recovery rate", "95% CI"], rows


CLOSED_LOOP_NOTE = ("disturbed: episodes in which a disturbance fired; recovery rate: successes among them (95% "
                    "Wilson interval); detection delay: mean primitives between a disturbance and the first action "
                    "that addresses it (unaddressed: events never addressed); extra primitives: mean primitives "
                    "beyond the ground-truth plan in recovered episodes")


def closed_loop_table(summary: dict[str, Any]) -> str:
    """The closed-loop tables of a run with disturbances (empty for one without): per task type and overall,
    then recovery per disturbance kind."""
    closed = _closed_loop_rows(summary)
    if closed is None:
        return ""
    lines = ["closed loop (recovery: successes among the episodes in which a disturbance fired, 95% Wilson interval; "
             "detection delay and extra primitives: means in primitives; docs/evaluation.md):", *text_table(*closed)]
    kinds = _kind_rows(summary)
    if kinds[1]:
        lines += ["", *text_table(*kinds, rule_before_last=False)]
    return "\n".join(lines)


def closed_loop_markdown(summary: dict[str, Any]) -> list[str]:
    """Markdown lines of ``closed_loop_table`` (none for a run without disturbances)."""
    closed = _closed_loop_rows(summary)
    if closed is None:
        return []
    lines = ["", f"Closed loop: {CLOSED_LOOP_NOTE}.", "", *markdown_table(*closed)]
    kinds = _kind_rows(summary)
    if kinds[1]:
        lines += ["", *markdown_table(*kinds)]
    return lines


def success_table(summary: dict[str, Any], title: str = "") -> str:
    """The results table: one row per task type and an overall row: success rate in percent with its 95% Wilson
    interval, then SPL and the measurement ratio (``-`` where no ground-truth plan says what was needed); for a run
    with disturbances, the closed-loop tables after it (``closed_loop_table``)."""
    rows = list(summary["templates"].items()) + [(OVERALL, summary[OVERALL])]
    width = max(len("task type"), *(len(name) for name, _ in rows))
    cis = [percent_interval(s["ci_low"], s["ci_high"]) for _, s in rows]
    ci_width = max(len("95% CI"), *(len(c) for c in cis))
    rule = f"{'-' * width}  --------  ---------  ------------  {'-' * ci_width}  ----  -----------"
    lines = [title] if title else []
    lines.append(f"{'task type'.ljust(width)}  episodes  successes  success rate  {'95% CI'.ljust(ci_width)}   SPL"
                 "  meas. ratio")
    lines.append(rule)
    for i, ((name, s), ci) in enumerate(zip(rows, cis)):
        if i == len(rows) - 1:
            lines.append(rule)
        lines.append(f"{name.ljust(width)}  {s['episodes']:8d}  {s['successes']:9d}  {100 * s['success_rate']:11.1f}%"
                     f"  {ci.ljust(ci_width)}  {_ratio(s.get('spl')):>4}  {_ratio(s.get('measurement_ratio')):>11}")
    closed = closed_loop_table(summary)
    return "\n".join(lines + (["", closed] if closed else []))


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


def _figure(value: float | None, form: str) -> str:
    return "-" if value is None else format(value, form)


def agent_lines(stats: dict[str, Any] | None, prices: dict[str, Any] | None = None) -> list[str]:
    """Markdown lines of the agent's own counters (none when the agent reports none): per task type and overall,
    tokens in and out per episode, tokens per success, the parse-failure rate and endpoint seconds per episode;
    where the counters have tokens, a table of their cost and latency (``cost_lines``)."""
    if not stats:
        return []
    lines = ["", "| task type | tokens in / episode | tokens out / episode | tokens / success | parse failures | "
             "agent latency / episode (s) |", "|---|---:|---:|---:|---:|---:|"]
    for name, s in [*stats["templates"].items(), (OVERALL, stats[OVERALL])]:
        if s is None:
            continue
        per = s["per_episode"]
        rate = s["parse_failure_rate"]
        lines.append(f"| {name} | {_figure(per.get(INPUT_TOKENS), '.0f')} | "
                     f"{_figure(per.get(OUTPUT_TOKENS), '.0f')} | {_figure(s['tokens_per_success'], '.0f')} | "
                     f"{'-' if rate is None else f'{100 * rate:.1f}%'} | {_figure(per.get('latency_s'), '.1f')} |")
    return lines + cost_lines(stats, prices)


def cost_lines(stats: dict[str, Any], prices: dict[str, Any] | None = None) -> list[str]:
    """Markdown lines of what the model calls cost, per task type and overall (``muble.evaluation.usage``): tokens,
    cost, cost per episode and per success, latency p50/p95 per request, requests sent and replies replayed from
    a ledger; none when the counters have no tokens."""
    if not (stats[OVERALL] or {}).get("usage"):
        return []
    rows = [[name, *usage_cells(s["usage"])] for name, s in [*stats["templates"].items(), (OVERALL, stats[OVERALL])]
            if s and s.get("usage")]
    return ["", f"Cost and latency (cost at the price table: {prices_text(prices)}; latency per request, retries and "
                "back-off included; replayed: replies read from the LLM ledger, which sent no request):", "",
            *markdown_table(["task type", *COST_HEADER], rows)]


def partial_split(evaluated: int, listed: int) -> dict[str, int] | None:
    """``{"first": evaluated, "of": listed}`` for a split of which a run evaluated only the first ``evaluated`` of
    its ``listed`` episodes (``evaluation.limit``); None for the whole split."""
    return {"first": int(evaluated), "of": int(listed)} if evaluated < listed else None


def partial_words(partial: dict[str, Any] | None) -> str:
    """How a limited run is labelled wherever its numbers are shown (``first 20 of 100 episodes``); empty for a
    run of the whole split."""
    if not partial:
        return ""
    return f"first {partial['first']} of {partial['of']} episodes"


def markdown(report: dict[str, Any], plots: dict[str, str]) -> str:
    """A Markdown summary of a report: per split, the success table, the failure taxonomy, timing and plot."""
    stamp = run_stamp(report.get("protocol"), report.get("track", "program"), report.get("mode", "graph"))
    lines = [f"# Evaluation of agent `{report['agent']}` ({stamp})", "",
             f"Dataset `{report['dataset']}`; seeds and versions in `report.json`, the shareable results in "
             "`results.json`. Success rates with their 95% Wilson score interval; SPL is success weighted by "
             "primitive count against the ground-truth plan, the measurement ratio the weighings and squeezes "
             "made over those the plans needed.", ""]
    for split, summary in report["splits"].items():
        covered = f" ({partial_words(summary['partial'])}: evaluation.limit)" if summary.get("partial") else ""
        lines += [f"## Split `{split}`{covered}", "",
                  "| task type | episodes | successes | success rate | 95% CI | SPL | meas. ratio |",
                  "|---|---:|---:|---:|---:|---:|---:|"]
        for t, s in summary["templates"].items():
            lines.append(f"| {t} | {s['episodes']} | {s['successes']} | {100 * s['success_rate']:.1f}% | "
                         f"{percent_interval(s['ci_low'], s['ci_high'])} | {_ratio(s.get('spl'))} | "
                         f"{_ratio(s.get('measurement_ratio'))} |")
        o = summary[OVERALL]
        lines += [f"| **{OVERALL}** | **{o['episodes']}** | **{o['successes']}** | "
                  f"**{100 * o['success_rate']:.1f}%** | **{percent_interval(o['ci_low'], o['ci_high'])}** | "
                  f"**{_ratio(o.get('spl'))}** | **{_ratio(o.get('measurement_ratio'))}** |", "",
                  "| failure class | episodes |", "|---|---:|"]
        lines += [f"| {c} | {n} |" for c, n in summary["failures"].items()]
        lines += closed_loop_markdown(summary)
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
        lines += agent_lines(summary.get("agent_stats"), report.get("prices"))
        if split in plots:
            lines += ["", f"![success rate per task type, split {split}]({plots[split]})"]
        lines.append("")
    return "\n".join(lines)
