"""Closed-loop metrics: how an agent does when the world deviates from its plan (docs/evaluation.md, "Closed-loop
metrics").

A record of a run with disturbances carries ``disturbances`` (the events that fired, each with the 1-based
``step`` of the primitive during or right after which it fired) and ``disturbances_planned``; records of other runs
have neither key, and nothing here is computed for them. From the records:

- recovery: success among the episodes in which at least one disturbance fired, overall and per disturbance kind
  (an episode counts once for every kind that fired in it), with the Wilson 95% interval;
- detection delay: per fired event, the primitives executed after the disturbed one before the first that
  addresses it (``addressing_index``); events never addressed are counted apart (``unaddressed``);
- extra primitives: primitives a successful disturbed episode used beyond its undisturbed ground-truth plan.
"""
from __future__ import annotations

import re
from typing import Any, Iterable

from muble.core.types import Outcome
from muble.evaluation.stats import wilson

# Kinds that spoil a reading instead of moving an object: the agent addresses one by measuring again, whichever
# object (a measuring primitive may name none: ``weigh()`` weighs what the hand holds).
READING_KINDS = frozenset({"sensor_dropout"})

_ACTION = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\((?P<args>.*)\)$")


def parse_action(text: str) -> tuple[str, dict[str, str]]:
    """A record's primitive string (``str(ActionCall)``) as its name and parameters, values as written:
    ``weigh(target=3)`` -> (``weigh``, {``target``: ``3``}); text that is not a call -> (text, {})."""
    m = _ACTION.match(text.strip())
    if not m:
        return text, {}
    args = {}
    for part in re.split(r",\s*(?=[A-Za-z_][A-Za-z0-9_]*=)", m.group("args")) if m.group("args") else []:
        key, _, value = part.partition("=")
        args[key.strip()] = value.strip()
    return m.group("name"), args


def has_disturbances(records: Iterable[dict[str, Any]]) -> bool:
    """Whether any record comes from a run with disturbances (has the ``disturbances`` key, fired or not)."""
    return any("disturbances" in r for r in records)


def fired_kinds(record: dict[str, Any]) -> list[str]:
    """The kinds of the disturbances that fired in the episode, in the order they fired (empty without)."""
    return [str(e.get("kind")) for e in record.get("disturbances") or []]


def _success(record: dict[str, Any]) -> bool:
    return record["outcome"] == Outcome.SUCCESS.value


def share(successes: int, episodes: int) -> dict[str, Any]:
    """``successes`` of ``episodes`` as a rate (None without episodes) with its Wilson 95% interval."""
    low, high = wilson(successes, episodes)
    return {"episodes": episodes, "successes": successes, "rate": successes / episodes if episodes else None,
            "ci_low": low, "ci_high": high}


def recovery_by_kind(episodes: Iterable[tuple[Iterable[str], bool]]) -> dict[str, dict[str, Any]]:
    """Per disturbance kind (sorted), ``share`` of the successes among the episodes in which one of that kind
    fired; ``episodes`` holds each episode's fired kinds and whether it succeeded."""
    counts: dict[str, list[int]] = {}
    for kinds, success in episodes:
        for kind in set(kinds):
            counts.setdefault(kind, [0, 0])
            counts[kind][0] += bool(success)
            counts[kind][1] += 1
    return {kind: share(*counts[kind]) for kind in sorted(counts)}


def _names_object(params: dict[str, str], obj: Any) -> bool:
    return params.get("target", "").strip("'\"") == str(obj)


def addressing_index(event: dict[str, Any], primitives: list[str], measuring: set[str]) -> int | None:
    """The 0-based index in ``primitives`` of the first primitive after the disturbed one (``primitives[step - 1]``)
    that addresses the event: for a kind in ``READING_KINDS`` a measuring one (``measuring``), for an event with
    an object one whose ``target`` names that object. None when none does (or the event has neither)."""
    reading = event.get("kind") in READING_KINDS
    obj = event.get("object")
    if not reading and obj is None:
        return None
    for i in range(max(int(event["step"]), 0), len(primitives)):
        name, params = parse_action(primitives[i])
        if name in measuring if reading else _names_object(params, obj):
            return i
    return None


def detection_delay(event: dict[str, Any], primitives: list[str], measuring: set[str]) -> int | None:
    """The primitives executed after the disturbed one before the one that addresses the event (0: the very next
    primitive addresses it); None when none does."""
    i = addressing_index(event, primitives, measuring)
    return None if i is None else i - int(event["step"])


def _mean(values: list[int]) -> float | None:
    return sum(values) / len(values) if values else None


def closed_loop(records: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The closed-loop metrics of ``records``; None when none of them comes from a run with disturbances.

    Returns ``disturbed`` (episodes with at least one fired disturbance), ``recovered`` (successes among them),
    ``recovery_rate`` (None when none was disturbed) with ``ci_low`` and ``ci_high``, ``recovery_by_kind``,
    ``disturbances_fired`` and ``disturbances_planned`` (sums), ``detection_delay`` (mean over addressed events;
    None when none was) with ``addressed`` and ``unaddressed`` counts, and ``extra_primitives`` (mean over
    successful disturbed episodes with a ground-truth plan; None when there is none) with their number
    ``extra_primitives_episodes``.
    """
    if not has_disturbances(records):
        return None
    from muble.plugins.registry import get_registry

    registry = get_registry()
    measuring = {name for name in registry.names("primitive") if registry.measures(name)}
    disturbed = [r for r in records if r.get("disturbances")]
    delays = [detection_delay(e, r.get("primitives") or [], measuring) for r in disturbed for e in r["disturbances"]]
    addressed = [d for d in delays if d is not None]
    extra = [len(r.get("primitives") or []) - r["ground_truth_primitives"] for r in disturbed
             if _success(r) and r.get("ground_truth_primitives", 0) > 0]
    rate = share(sum(map(_success, disturbed)), len(disturbed))
    return {"disturbed": rate["episodes"], "recovered": rate["successes"], "recovery_rate": rate["rate"],
            "ci_low": rate["ci_low"], "ci_high": rate["ci_high"],
            "recovery_by_kind": recovery_by_kind((fired_kinds(r), _success(r)) for r in disturbed),
            "disturbances_fired": len(delays),
            "disturbances_planned": sum(int(r.get("disturbances_planned") or 0) for r in records),
            "detection_delay": _mean(addressed), "addressed": len(addressed),
            "unaddressed": len(delays) - len(addressed),
            "extra_primitives": _mean(extra), "extra_primitives_episodes": len(extra)}
