"""Comparing evaluation runs: success per task type with its 95% interval, and paired tests on shared episodes.

Two agents evaluated on the same split ran the same episodes, so they are compared episode by episode: an episode
is shared when both runs have it (same split and index). Of the shared episodes only the discordant ones tell the
agents apart: ``b`` episodes the first run solved and the second did not, ``c`` the reverse. The exact McNemar
test (``muble.evaluation.stats.mcnemar_exact``) says how likely a split at least as uneven as ``b`` to ``c`` is
if the agents were equally good; with paired episodes this is far more sensitive than comparing two intervals.

Every pair of runs is compared, overall and per task type (the first run's template of each shared episode).
Runs that followed different protocols, tracks or observation modes, or ran on data with another hash, are
compared all the same but with a warning: their numbers answer different questions. Runs that share no episode
cannot be paired at all and are refused. Runs of an agent that counts its tokens (``agent=llm``) are also set side
by side in what they cost and how long their requests waited (``muble.evaluation.usage``).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError
from muble.core.types import Outcome
from muble.evaluation.closed_loop import recovery_by_kind, share
from muble.evaluation.report import OVERALL, UNKNOWN, markdown_table, partial_words, percent_interval, text_table
from muble.evaluation.stats import mcnemar_exact, wilson
from muble.evaluation.usage import COST_HEADER, PriceTable, prices_text, usage_cells, usage_summary

FORMAT = "muble-compare"
VERSION = 1
CHART = "compare.png"
# What a run followed; runs that differ in one of these are warned about (field -> how a warning names it).
SETTINGS = {"protocol": "protocols", "protocol_split": "protocol splits", "data_sha256": "data (dataset manifest "
            "sha256)", "track": "tracks", "mode": "observation modes"}


@dataclass(frozen=True)
class Run:
    """One ``muble eval`` run: its label in tables, its folder and its checked results file."""

    label: str
    folder: Path
    results: dict[str, Any]

    def episodes(self) -> dict[tuple[str, int], dict[str, Any]]:
        """Every episode of the run by (split, index)."""
        return {(split, e["index"]): e for split, entry in self.results["splits"].items() for e in entry["episodes"]}


def labelled(folders: list[Path], results: list[dict[str, Any]]) -> list[Run]:
    """Runs labelled by folder name; where two names are the same, by the folders as given, and where those are
    the same too (one folder passed twice), numbered."""
    names = [f.resolve().name or str(f) for f in folders]
    labels = [name if names.count(name) == 1 else str(f) for name, f in zip(names, folders)]
    labels = [label if labels.count(label) == 1 else f"{label} #{labels[:i].count(label) + 1}"
              for i, label in enumerate(labels)]
    return [Run(label, f, r) for label, f, r in zip(labels, folders, results)]


def _success(episode: dict[str, Any]) -> bool:
    return episode["outcome"] == Outcome.SUCCESS.value


def _rate(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    successes = sum(map(_success, episodes))
    low, high = wilson(successes, len(episodes))
    return {"episodes": len(episodes), "successes": successes,
            "rate": successes / len(episodes) if episodes else None, "ci": [low, high]}


def _recovery(episodes: list[dict[str, Any]]) -> dict[str, dict[str, Any]] | None:
    """Per disturbance kind and overall, success among the episodes in which a disturbance fired, in ``_rate``'s
    form; None for a run without disturbances (its results file lists no ``disturbance_kinds``)."""
    if not any("disturbance_kinds" in e for e in episodes):
        return None
    disturbed = [(e["disturbance_kinds"], _success(e)) for e in episodes if e.get("disturbance_kinds")]
    rows = {**recovery_by_kind(disturbed), OVERALL: share(sum(ok for _, ok in disturbed), len(disturbed))}
    return {group: {"episodes": r["episodes"], "successes": r["successes"], "rate": r["rate"],
                    "ci": [r["ci_low"], r["ci_high"]]} for group, r in rows.items()}


def _usage(run: Run, episodes: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The run's tokens, cost and latency (``muble.evaluation.usage.usage_summary``) over all its episodes, with
    the price table its agent's config gives (``prices``); None for a run without token counters."""
    usage = usage_summary(episodes)
    if usage is None:
        return None
    prices = PriceTable.of(run.results.get("agent_config"))
    return {**usage, "prices": None if prices is None else prices.as_dict()}


def _template_order(runs: list[Run]) -> list[str]:
    """Task types in the order the runs' summaries list them (the template mix), others after, ``unknown`` last."""
    order: list[str] = []
    for run in runs:
        for entry in run.results["splits"].values():
            listed = list(entry.get("summary", {}).get("templates", {}))
            for template in listed + sorted({e["template"] for e in entry["episodes"]}):
                if template not in order:
                    order.append(template)
    return [t for t in order if t != UNKNOWN] + ([UNKNOWN] if UNKNOWN in order else [])


def _paired(first: dict[tuple[str, int], dict[str, Any]], second: dict[tuple[str, int], dict[str, Any]],
            keys: list[tuple[str, int]]) -> dict[str, Any]:
    b = sum(1 for k in keys if _success(first[k]) and not _success(second[k]))
    c = sum(1 for k in keys if not _success(first[k]) and _success(second[k]))
    return {"shared": len(keys), "first_successes": sum(_success(first[k]) for k in keys),
            "second_successes": sum(_success(second[k]) for k in keys), "b": b, "c": c,
            "p_value": mcnemar_exact(b, c)}


def _warnings(runs: list[Run]) -> list[str]:
    out = []
    for field, what in SETTINGS.items():
        values = {run.label: run.results.get(field) for run in runs}
        if len(set(map(repr, values.values()))) > 1:
            listing = ", ".join(f"{label}: {value if value is not None else 'none'}" for label, value in values.items())
            out.append(f"the runs used different {what} ({listing}); their rates are not of the same benchmark")
    return out


def _covered(run: Run) -> str:
    """What a run evaluated, per split: ``mini (first 20 of 100 episodes)`` or ``mini (100 episodes)``."""
    # Each part's words apart: an f-string may not reuse its outer quote inside a field before Python 3.12.
    words = {split: partial_words(entry.get("partial")) or f"{len(entry['episodes'])} episodes"
             for split, entry in run.results["splits"].items()}
    return ", ".join(f"{split} ({covered})" for split, covered in words.items())


def compare(runs: list[Run]) -> dict[str, Any]:
    """The comparison of ``runs`` (at least one): each run's success per task type and overall with its Wilson
    interval, every pair's shared episodes, discordant counts and McNemar p-value, overall and per task type, and
    warnings; where a run had disturbances, ``recovery`` (per run, per disturbance kind and overall, ``None`` for a
    run without); where a run counted tokens, ``usage`` (per run, ``_usage``; ``None`` for a run without).
    Raises ``ConfigError`` when two runs share no episode."""
    templates = _template_order(runs)
    episodes = {run.label: run.episodes() for run in runs}
    success: dict[str, dict[str, Any]] = {}
    for run in runs:
        mine = list(episodes[run.label].values())
        success[run.label] = {t: _rate([e for e in mine if e["template"] == t]) for t in templates}
        success[run.label][OVERALL] = _rate(mine)
    recovery = {run.label: _recovery(list(episodes[run.label].values())) for run in runs}
    usage = {run.label: _usage(run, list(episodes[run.label].values())) for run in runs}
    warnings = _warnings(runs)
    pairs = []
    for one, other in itertools.combinations(runs, 2):
        first, second = episodes[one.label], episodes[other.label]
        shared = sorted(first.keys() & second.keys())
        if not shared:
            raise ConfigError(
                f"runs {one.label} ({one.folder}) and {other.label} ({other.folder}) share no episode (same split and "
                f"index): {one.label} has splits {', '.join(one.results['splits']) or 'none'}, {other.label} has "
                f"{', '.join(other.results['splits']) or 'none'}; compare runs evaluated on the same split")
        if len(shared) < max(len(first), len(second)):
            warnings.append(f"{one.label} ran {_covered(one)} and {other.label} {_covered(other)}: they share "
                            f"{len(shared)} episodes, so their success rates are over different episodes; the "
                            "paired tests use the shared ones only")
        relabelled = sum(1 for k in shared if first[k]["template"] != second[k]["template"])
        if relabelled:
            warnings.append(f"{relabelled} of the episodes {one.label} and {other.label} share have different task "
                            "types in the two runs: they did not run on the same data")
        per_template = {t: _paired(first, second, [k for k in shared if first[k]["template"] == t])
                        for t in templates}
        pairs.append({"first": one.label, "second": other.label, OVERALL: _paired(first, second, shared),
                      "templates": {t: v for t, v in per_template.items() if v["shared"]}})
    return {"format": FORMAT, "version": VERSION,
            "runs": [{"label": run.label, "folder": str(run.folder), "agent": run.results.get("agent"),
                      "splits": list(run.results["splits"]), **{f: run.results.get(f) for f in SETTINGS},
                      "partial": {split: entry["partial"] for split, entry in run.results["splits"].items()
                                  if entry.get("partial")}}
                     for run in runs],
            "warnings": warnings, "templates": templates, "success": success, "pairs": pairs,
            # Only where a run had disturbances: other comparisons are as they were.
            **({"recovery": recovery} if any(recovery.values()) else {}),
            # Only where a run counted tokens (an LLM agent), likewise.
            **({"usage": usage} if any(usage.values()) else {})}


def chart_groups(comparison: dict[str, Any]) -> dict[str, dict[str, tuple[float, float, float] | None]]:
    """``muble.evaluation.plot.interval_chart``'s input: per task type and overall, each run's (rate, low, high)."""
    labels = [run["label"] for run in comparison["runs"]]
    groups = {}
    for group in [*comparison["templates"], OVERALL]:
        rows = {label: comparison["success"][label][group] for label in labels}
        groups[group] = {label: None if row["rate"] is None else (row["rate"], *row["ci"])
                         for label, row in rows.items()}
    return groups


def _cell(row: dict[str, Any]) -> str:
    if row["rate"] is None:
        return "- (n=0)"
    return f"{100 * row['rate']:.1f}% {percent_interval(*row['ci'])} n={row['episodes']}"


def _p(value: float) -> str:
    return f"{value:.3g}"


def _success_rows(comparison: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    labels = [run["label"] for run in comparison["runs"]]
    rows = [[group] + [_cell(comparison["success"][label][group]) for label in labels]
            for group in [*comparison["templates"], OVERALL]]
    return ["task type", *labels], rows


def _recovery_rows(comparison: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Per disturbance kind and overall, each run's recovery rate (``-`` for a run without disturbances)."""
    labels = [run["label"] for run in comparison["runs"]]
    recovery = comparison["recovery"]
    kinds = sorted({kind for rows in recovery.values() if rows for kind in rows if kind != OVERALL})
    rows = [[group] + [_cell(recovery[label][group]) if group in (recovery[label] or {}) else "-" for label in labels]
            for group in [*kinds, OVERALL]]
    return ["disturbance kind", *labels], rows


def _usage_rows(comparison: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Per run, its tokens, cost, latency and ledger replays (``-`` for a run without token counters)."""
    rows = [[label, *(usage_cells(u) if u else ["-"] * len(COST_HEADER))]
            for label, u in comparison["usage"].items()]
    return ["run", *COST_HEADER], rows


def _usage_notes(comparison: dict[str, Any]) -> list[str]:
    """Each run's price table, which its costs are at."""
    return [f"{label}: {prices_text(u['prices'])}" for label, u in comparison["usage"].items() if u]


USAGE_NOTE = ("tokens, cost at each run's price table, latency per request (p50 / p95, retries included) and the "
              "requests sent and replies replayed from an LLM ledger, over all episodes of each run")


RECOVERY_NOTE = ("success among the episodes in which a disturbance fired, per disturbance kind and overall (95% "
                 "Wilson interval, n episodes)")


def _pair_rows(pair: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    header = ["task type", "shared", f"{pair['first']} only (b)", f"{pair['second']} only (c)", "McNemar p"]
    rows = [[t, str(v["shared"]), str(v["b"]), str(v["c"]), _p(v["p_value"])]
            for t, v in [*pair["templates"].items(), (OVERALL, pair[OVERALL])]]
    return header, rows


def text(comparison: dict[str, Any]) -> str:
    """The comparison as printed: the success table, the recovery table of runs with disturbances, the cost and
    latency table of runs with token counters, then one table per pair, then the warnings."""
    lines = [f"success rate by task type (95% Wilson interval, n episodes), {len(comparison['runs'])} runs:"]
    lines += [f"  {run['label']}: agent {run['agent']}, {run['folder']}"
              + "".join(f"; {split}: {partial_words(p)}" for split, p in (run.get("partial") or {}).items())
              for run in comparison["runs"]]
    lines += ["", *text_table(*_success_rows(comparison))]
    if "recovery" in comparison:
        lines += ["", f"recovery rate after disturbances: {RECOVERY_NOTE}:", *text_table(*_recovery_rows(comparison))]
    if "usage" in comparison:
        lines += ["", f"cost and latency: {USAGE_NOTE}:",
                  *text_table(*_usage_rows(comparison), rule_before_last=False),
                  *[f"  {note}" for note in _usage_notes(comparison)]]
    for pair in comparison["pairs"]:
        o = pair[OVERALL]
        lines += ["", f"{pair['first']} vs {pair['second']}: {o['shared']} shared episodes, {o['b']} solved only by "
                      f"{pair['first']}, {o['c']} only by {pair['second']}; exact McNemar p = {_p(o['p_value'])}",
                  *text_table(*_pair_rows(pair))]
    if comparison["warnings"]:
        lines += [""] + [f"warning: {w}" for w in comparison["warnings"]]
    return "\n".join(lines)


def markdown(comparison: dict[str, Any], chart: str | None = CHART) -> str:
    """``compare.md``: the runs, warnings, the success table with the chart, the recovery table of runs with
    disturbances, the cost and latency table of runs with token counters, and the paired tests."""
    lines = [f"# Comparison of {len(comparison['runs'])} evaluation runs", "",
             "| run | agent | folder | protocol | track | mode | data sha256 |", "|---|---|---|---|---|---|---|"]
    for run in comparison["runs"]:
        sha = (run["data_sha256"] or "none")[:12]
        protocol = run["protocol"] or "none"
        if run["protocol_split"]:
            protocol += f" ({run['protocol_split']})"
        for split, partial in (run.get("partial") or {}).items():
            protocol += f", {split}: {partial_words(partial)}"
        lines.append(f"| {run['label']} | {run['agent']} | `{run['folder']}` | {protocol} | {run['track']} | "
                     f"{run['mode']} | `{sha}` |")
    if comparison["warnings"]:
        lines += ["", "**Warnings:**", ""] + [f"- {w}" for w in comparison["warnings"]]
    lines += ["", "## Success by task type", "",
              "Success rate, its 95% Wilson score interval and the number of episodes n.", "",
              *markdown_table(*_success_rows(comparison))]
    if chart:
        lines += ["", f"![success rate per task type with 95% intervals]({chart})"]
    if "recovery" in comparison:
        lines += ["", "## Recovery after disturbances", "", f"Recovery rate: {RECOVERY_NOTE}.", "",
                  *markdown_table(*_recovery_rows(comparison))]
    if "usage" in comparison:
        lines += ["", "## Cost and latency", "", f"{USAGE_NOTE[0].upper()}{USAGE_NOTE[1:]}.", "",
                  *markdown_table(*_usage_rows(comparison)), "", *[f"- {note}" for note in _usage_notes(comparison)]]
    lines += ["", "## Paired comparisons", "",
              "Over the episodes both runs have (same split and index): b episodes only the first run solved, c only "
              "the second; the p-value is the exact two-sided McNemar test (binomial on b + c discordant episodes)."]
    for pair in comparison["pairs"]:
        lines += ["", f"### {pair['first']} vs {pair['second']}", "", *markdown_table(*_pair_rows(pair))]
    lines.append("")
    return "\n".join(lines)
