"""The ``llm`` agent's options (``agent=llm``; ``muble_conf/agent/llm.yaml`` extends this schema)."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from muble.core.ranges import bounded


class ImagePolicy(str, Enum):
    """When the observation's images go into the step's message (as data URLs, for vision models)."""

    auto = "auto"  # when the scene has no attribute words to read (observation modes masks and image)
    always = "always"
    never = "never"


class SchemaForm(str, Enum):
    """How the JSON schema is sent as ``response_format``: servers accept one form or the other."""

    json_schema = "json_schema"  # OpenAI's {"type": "json_schema", "json_schema": {"schema": ...}}: OpenAI, vLLM,
    # Ollama, LM Studio, llama.cpp's llama-server
    json_object = "json_object"  # {"type": "json_object", "schema": ...}: llama-cpp-python's server


class LedgerMode(str, Enum):
    """How the agent uses its LLM ledger (``muble_plugins.llm.ledger``), the store of every reply by its request."""

    read_write = "read_write"  # replay what is recorded; ask the endpoint for the rest and record it
    read_only = "read_only"  # replay only: a request the ledger lacks ends its episode as agent_error
    off = "off"  # no ledger: every request is sent, nothing is recorded


@dataclass
class LlmConfig:
    """Where the endpoint is, how to ask it and what to tell it.

    The key is never an option: ``api_key_env`` names the environment variable that holds it, so configs, results
    and logs can be shared. ``timeout`` bounds one request; a request that exceeds it ends the episode as
    ``agent_error``. HTTP 429, 5xx and dropped connections are retried ``http_retries`` times, waiting what
    Retry-After asks (at most ``max_backoff`` seconds) or else 1, 2, 4 … s. A reply that is not one valid JSON
    decision is sent back with the error ``max_retries`` times; then the episode ends as ``invalid_action``.

    The ledger keeps every reply under its request (model, sampling settings and messages), so a run that is
    resumed or run again replays them instead of asking again. The ``price_*`` options are the price table every
    cost in the reports is computed at (``muble.io.usage_fields.PriceTable``): USD per million tokens, as the
    provider's price list gave them on ``price_date``; 0 for a local model.
    """

    base_url: str = "http://127.0.0.1:8080/v1"
    model: str = "local"  # the endpoint's model name (a local server serving one model accepts any)
    api_key_env: str = "OPENAI_API_KEY"  # the NAME of the variable holding the key; unset: no key is sent
    temperature: float = bounded(0.0, ge=0)
    max_tokens: int = bounded(256, ge=1)
    timeout: float = bounded(60.0, gt=0)  # seconds per request
    max_retries: int = bounded(2, ge=0)  # re-asks after an unparseable or invalid reply, per step
    http_retries: int = bounded(4, ge=0)  # retries after 429, 5xx or a dropped connection, per request
    max_backoff: float = bounded(30.0, ge=0)  # the longest wait between two tries (Retry-After included), s
    schema: bool = True  # constrain replies with a JSON-schema response_format; false: parse the text
    schema_form: SchemaForm = SchemaForm.json_schema
    system_prompt: str | None = None  # path of the system prompt template; None: prompts/system.md of the package
    step_prompt: str | None = None  # path of the per-step message template; None: prompts/step.md of the package
    history: int = bounded(8, ge=0)  # past steps shown in each step's message
    images: ImagePolicy = ImagePolicy.auto
    examples: int = bounded(0, ge=0)  # worked examples from a split's ground-truth sequences in the system prompt
    examples_root: str | None = None  # a dataset folder written by `muble generate` (with dataset.sequences=true)
    examples_split: str = "train"
    # One JSONL file of requests and replies per episode. None: llm_logs/ in the run's output folder, where the run
    # gives one (muble eval does: beside the records); elsewhere no log.
    log_dir: str | None = None
    # Sent as the request's seed (OpenAI's `seed`), so a sampled reply (temperature > 0) can be drawn again on a
    # server that honours it; recorded with the reply in the ledger. None: no seed is sent.
    seed: int | None = bounded(None, ge=0)
    # The LLM ledger's folder; share one between runs to replay their replies. None: llm_ledger/ in the run's output
    # folder, where the run gives one (muble eval does); elsewhere no ledger.
    ledger: str | None = None
    ledger_mode: LedgerMode = LedgerMode.read_write
    price_input_per_mtok: float = bounded(0.0, ge=0)  # USD per million input tokens not read from a cache
    price_output_per_mtok: float = bounded(0.0, ge=0)  # USD per million output tokens
    price_cached_per_mtok: float | None = bounded(None, ge=0)  # USD per million cached input tokens; None: input's
    price_date: str | None = None  # when the prices were read from the provider's list (YYYY-MM-DD)
