"""What a run's model calls cost: tokens, US dollars and latency (docs/llm_agents.md, "Costs and latency").

An agent behind a model endpoint (``agent=llm``) reports, per episode, its token counts under OpenTelemetry
GenAI's names in ``agent_stats`` (``INPUT_TOKENS`` counts every input token, the cached ones
``CACHED_INPUT_TOKENS`` included), ``cost_usd`` (the tokens at the agent's ``PriceTable``), and in
``agent_samples`` the latency of each request. ``usage_summary`` derives, for any group of records, the totals,
the cost per episode, per success and of the group, and the latency's p50 and p95 per request; the report, the
results file, ``muble compare`` and the site all show these figures, and only for runs whose records have token
counters (other agents' reports are unchanged).
"""
from __future__ import annotations

from typing import Any, Iterable, Mapping

from muble.core.types import Outcome
from muble.evaluation.stats import quantile

from muble.io.usage_fields import (CACHED_INPUT_TOKENS, COST, INPUT_TOKENS, LATENCY, LEGACY_NAMES, MILLION,  # noqa: F401
                                   OUTPUT_TOKENS, REPLAYED, SENT, TOKENS, PriceTable)


def current_names(stats: Mapping[str, Any]) -> dict[str, Any]:
    """An episode's counters with the token counters of older records under their OpenTelemetry names."""
    return {LEGACY_NAMES.get(key, key): value for key, value in stats.items()}


def episode_usage(record: Mapping[str, Any]) -> dict[str, Any] | None:
    """One episode's usage: its token counts, cost, requests sent and replayed, and the latency of each request
    (``LATENCY``: a list). A results file's episode carries it as ``usage``; a record has it in ``agent_stats``
    and ``agent_samples``. None for an episode without token counters."""
    if isinstance(record.get("usage"), Mapping):
        return dict(record["usage"])
    stats = current_names(record.get("agent_stats") or {})
    if INPUT_TOKENS not in stats:
        return None
    usage = {key: stats[key] for key in (*TOKENS, COST, SENT, REPLAYED) if key in stats}
    usage[LATENCY] = [float(s) for s in (record.get("agent_samples") or {}).get(LATENCY) or []]
    return usage


def usage_summary(records: Iterable[Mapping[str, Any]]) -> dict[str, Any] | None:
    """The usage of a group of records (report rows, a results file's episodes): ``episodes`` and ``successes``
    with usage, the token totals (``TOKENS``), ``requests`` sent and ``replayed``, ``cost_usd`` (the group's),
    ``cost_per_episode_usd`` and ``cost_per_success_usd`` (None without a success; all three None where an
    episode has no cost), and the latency per request: ``latency_requests`` (how many), ``latency_p50_s`` and
    ``latency_p95_s`` (None without any). None when no record has token counters."""
    used = [(usage, record["outcome"] == Outcome.SUCCESS.value) for record in records
            if (usage := episode_usage(record)) is not None]
    if not used:
        return None
    episodes, successes = len(used), sum(success for _, success in used)
    cost = sum(u[COST] for u, _ in used) if all(COST in u for u, _ in used) else None
    latencies = [s for u, _ in used for s in u.get(LATENCY) or []]
    return {"episodes": episodes, "successes": successes,
            **{key: sum(u.get(key, 0) for u, _ in used) for key in (*TOKENS, SENT, REPLAYED)},
            COST: cost, "cost_per_episode_usd": None if cost is None else cost / episodes,
            "cost_per_success_usd": cost / successes if cost is not None and successes else None,
            "latency_requests": len(latencies), "latency_p50_s": quantile(latencies, 0.5),
            "latency_p95_s": quantile(latencies, 0.95)}


# --- how reports show it ----------------------------------------------------------------------------------------
def dollars(value: float | None) -> str:
    """``$0.0123``: four decimals, enough for a cent's fraction per episode; ``-`` for none."""
    return "-" if value is None else f"${value:.4f}"


def seconds_p50_p95(usage: Mapping[str, Any]) -> str:
    """``0.41 / 1.90``: the latency's p50 and p95 in seconds; ``-`` without requests."""
    if usage.get("latency_p50_s") is None:
        return "-"
    return f"{usage['latency_p50_s']:.2f} / {usage['latency_p95_s']:.2f}"


def prices_text(prices: Mapping[str, Any] | None) -> str:
    """The price table in words, for a note under a cost table."""
    if not prices:
        return "no price table"
    when = f", read {prices['date']}" if prices.get("date") else ", undated"
    return (f"USD per million tokens: input {prices['input_per_mtok']:g}, cached input {prices['cached_per_mtok']:g}, "
            f"output {prices['output_per_mtok']:g}{when}")


COST_HEADER = ["tokens in", "of them cached", "tokens out", "cost", "cost / episode", "cost / success",
               "latency p50 / p95 (s)", "requests sent", "replayed"]


def usage_cells(usage: Mapping[str, Any]) -> list[str]:
    """The cells of ``COST_HEADER`` for one usage summary."""
    return [f"{usage[INPUT_TOKENS]:.0f}", f"{usage[CACHED_INPUT_TOKENS]:.0f}", f"{usage[OUTPUT_TOKENS]:.0f}",
            dollars(usage[COST]), dollars(usage["cost_per_episode_usd"]), dollars(usage["cost_per_success_usd"]),
            seconds_p50_p95(usage), f"{usage[SENT]:.0f}", f"{usage[REPLAYED]:.0f}"]
