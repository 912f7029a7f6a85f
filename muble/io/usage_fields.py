"""The fields in which an agent reports what its model calls used, and the price table that turns tokens into US
dollars: written by agents (``agent=llm``) into their episode counters, read by the reports
(``muble.evaluation.usage``). Token counts carry OpenTelemetry GenAI's names."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

# OpenTelemetry GenAI semantic conventions (gen-ai-spans): input tokens include the cached ones.
INPUT_TOKENS = "gen_ai.usage.input_tokens"
OUTPUT_TOKENS = "gen_ai.usage.output_tokens"
CACHED_INPUT_TOKENS = "gen_ai.usage.cache_read.input_tokens"
TOKENS = (INPUT_TOKENS, CACHED_INPUT_TOKENS, OUTPUT_TOKENS)
COST = "cost_usd"
LATENCY = "latency_s"  # in agent_samples: the seconds each request waited for its reply
# Counters of what this run itself sent, beside what the episode used: a replayed reply sends no request.
SENT, REPLAYED = "requests", "replayed"
# Token counters of records written before the OpenTelemetry names (read back by a resumed run) -> their names.
LEGACY_NAMES = {"tokens_in": INPUT_TOKENS, "tokens_out": OUTPUT_TOKENS}
MILLION = 1_000_000


@dataclass(frozen=True)
class PriceTable:
    """US dollars per million tokens, as a provider's price list gave them on ``date`` (its version): input tokens
    not read from the provider's cache, cached input tokens (None: the input price) and output tokens. All 0 for
    a local model."""

    input_per_mtok: float = 0.0
    output_per_mtok: float = 0.0
    cached_per_mtok: float | None = None
    date: str | None = None

    # The agent options a price table is read from (``agent.price_*``): field -> option.
    OPTIONS: ClassVar[dict[str, str]] = {
        "input_per_mtok": "price_input_per_mtok", "output_per_mtok": "price_output_per_mtok",
        "cached_per_mtok": "price_cached_per_mtok", "date": "price_date"}

    @classmethod
    def of(cls, agent_config: Mapping[str, Any] | None) -> "PriceTable | None":
        """The price table of an agent's config section (``agent.price_*``); None for an agent without one."""
        config = agent_config or {}
        if not any(option in config for option in cls.OPTIONS.values()):
            return None
        return cls(**{name: config[option] for name, option in cls.OPTIONS.items() if option in config})

    def cost_usd(self, input_tokens: float, output_tokens: float, cached_tokens: float = 0.0) -> float:
        """What the tokens cost: the uncached input tokens at the input price, the cached ones at the cached
        price, the output tokens at the output price."""
        cached_price = self.input_per_mtok if self.cached_per_mtok is None else self.cached_per_mtok
        return ((input_tokens - cached_tokens) * self.input_per_mtok + cached_tokens * cached_price
                + output_tokens * self.output_per_mtok) / MILLION

    def as_dict(self) -> dict[str, Any]:
        return {"input_per_mtok": self.input_per_mtok, "output_per_mtok": self.output_per_mtok,
                "cached_per_mtok": self.input_per_mtok if self.cached_per_mtok is None else self.cached_per_mtok,
                "date": self.date}
