"""The ``llm`` agent: each step one chat completion, turned into the next primitive, an answer or a stop.

Per step the agent renders the step message (``prompts/step.md``) under the episode's system prompt
(``prompts/system.md``), asks the endpoint (``muble_plugins.llm.endpoint``) and parses the reply
(``muble_plugins.llm.reply``). A reply that is not one valid decision is sent back with the error, up to
``max_retries`` times; after that the agent returns an ``UnusableReply``, which is no action, so the action loop
ends the episode as ``invalid_action`` with the reason in the record's error. An endpoint that times out or keeps
failing raises, which ends the episode as ``agent_error``. After an answer the agent stops: the answer is the
query's end.

``stats()`` gives the episode's counters (requests sent, replies replayed from the ledger, replies, parse failures,
re-asks, HTTP retries, tokens in, cached and out, their cost at the price table, latency) and ``samples()`` the
seconds each reply took; ``muble eval`` stores them on the episode's record and the report derives cost and latency
percentiles from them.

Every reply goes into the LLM ledger (``muble_plugins.llm.ledger``; ``agent.ledger``, by default ``llm_ledger/``
beside the records), and a request the ledger has a reply to is replayed from it, not sent: a run resumed or run
again asks nothing it asked before.
"""
from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import Any

from muble import ActionCall, Agent, Answer, ConfigError, Instruction, Observation, ObservationMode, Track
from muble.core.ranges import configured

from muble.io.usage_fields import PriceTable

from muble_plugins.llm.config import ImagePolicy, LedgerMode, LlmConfig
from muble_plugins.llm.endpoint import Endpoint, EpisodeStats, ExchangeLog
from muble_plugins.llm.examples import load_examples, pick_examples
from muble_plugins.llm.ledger import FOLDER as LEDGER_FOLDER, Ledger
from muble_plugins.llm.prompt import (RETRY_FIELDS, STEP_FIELDS, SYSTEM_FIELDS, PromptTemplate, Turn, examples_text,
                                      history_text, image_parts, object_form, primitives_text, program_text,
                                      result_text, scene_text)
from muble_plugins.llm.reply import ReplyError, decision_schema, parse_reply

log = logging.getLogger(__name__)

LOG_FOLDER = "llm_logs"  # in the run's output folder, when agent.log_dir is not set


class UnusableReply:
    """The decision of a step whose replies could not be used: not an action, so the episode ends as
    ``invalid_action``. Its text, which the action loop records (cut at 80 characters), names the fault first;
    ``reason`` has the whole message, as the episode's log does."""

    def __init__(self, kind: str, reason: str, tries: int) -> None:
        self.kind, self.reason, self.tries = kind, reason, tries

    def __repr__(self) -> str:
        return f"{self.kind} in {self.tries} replies (the log has them): {self.reason}"


class LlmAgent(Agent):
    """Plans with a chat model behind an OpenAI-compatible endpoint; see the module's docstring.

    Built from an ``LlmConfig`` (the registry's checked instance) and/or keyword overrides of its fields
    (``LlmAgent(base_url="http://127.0.0.1:11434/v1", model="qwen2.5")``), checked against the schema's types and
    bounds.
    """

    def __init__(self, config: LlmConfig | None = None, **options: Any) -> None:
        self.config = cfg = configured(LlmConfig, config, options, owner="agent 'llm'")
        self.endpoint = Endpoint(cfg.base_url, cfg.model, cfg.api_key_env, cfg.temperature, cfg.max_tokens,
                                 cfg.timeout, cfg.http_retries, cfg.max_backoff, cfg.schema_form.value, cfg.seed)
        self.prices = PriceTable.of(vars(cfg)) or PriceTable()
        self.max_retries, self.schema, self.history = cfg.max_retries, cfg.schema, cfg.history
        self.images = cfg.images
        # Prompt files are read and checked now, so a wrong path or placeholder stops the run before any episode.
        self.system_template = PromptTemplate.load(cfg.system_prompt, "system.md", SYSTEM_FIELDS)
        self.step_template = PromptTemplate.load(cfg.step_prompt, "step.md", STEP_FIELDS)
        self.retry_template = PromptTemplate.load(None, "retry.md", RETRY_FIELDS)
        if cfg.examples and not cfg.examples_root:
            raise ConfigError("agent.examples needs agent.examples_root: a dataset folder written by `muble "
                              "generate` with ground-truth sequences (its agent.examples_split split)")
        self.examples = cfg.examples
        self.example_pool = (load_examples(Path(cfg.examples_root), cfg.examples_split)
                             if cfg.examples and cfg.examples_root else [])
        self.log_dir = Path(cfg.log_dir) if cfg.log_dir else None
        self.output_dir: Path | None = None  # set by muble eval: the logs then go beside its records
        self.record = ExchangeLog()
        self.episode_stats = EpisodeStats()
        self.turns: list[Turn] = []
        self.system = ""
        self.answered = False
        self.view = ObservationMode.graph
        self.episode = "this episode"  # named in errors: split, index and template

    # The episode's parts -------------------------------------------------------------------------------------

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        self.episode_stats = EpisodeStats()
        self.turns = []
        self.answered = False
        self.view = ObservationMode(mode)
        chosen = pick_examples(self.example_pool, instruction.template_id, self.examples)
        self.system = self.system_template.render(
            primitives=primitives_text(self.view), object_form=object_form(self.view),
            examples=examples_text(chosen, Track(track)))
        self.record.open(self._log_path(instruction))
        self.endpoint.ledger = self._ledger()
        self.episode = f"episode {instruction.split or '-'} {instruction.image_index} ({instruction.template_id})"
        self.record.write("episode", instruction=instruction.instruction, template=instruction.template_id,
                          split=instruction.split, index=instruction.image_index, view=self.view,
                          model=self.endpoint.model, base_url=self.endpoint.base_url, schema=self.schema)

    def _log_path(self, instruction: Instruction) -> Path | None:
        folder = self.log_dir or (self.output_dir / LOG_FOLDER if self.output_dir is not None else None)
        if folder is None:
            return None
        stem = f"{instruction.split or 'episode'}_{instruction.image_index:06d}_{instruction.template_id}"
        return folder / (re.sub(r"[^A-Za-z0-9_.-]", "_", stem) + ".jsonl")

    def _ledger(self) -> Ledger | None:
        """The ledger of this episode: ``agent.ledger``, else ``llm_ledger/`` in the run's output folder; None when
        ``agent.ledger_mode=off`` or outside a run that gives an output folder."""
        cfg = self.config
        if cfg.ledger_mode is LedgerMode.off:
            return None
        folder = Path(cfg.ledger) if cfg.ledger else (
            self.output_dir / LEDGER_FOLDER if self.output_dir is not None else None)
        if folder is None:
            if cfg.ledger_mode is LedgerMode.read_only:
                raise ConfigError("agent.ledger_mode=read_only replays a ledger: set agent.ledger to its folder")
            return None
        return Ledger(folder, cfg.ledger_mode)

    def stats(self) -> dict[str, float]:
        """This episode's counters (see ``EpisodeStats``) with their cost at the price table; read by ``muble eval``
        after the episode."""
        return self.episode_stats.as_dict(self.prices)

    def samples(self) -> dict[str, list[float]]:
        """The seconds each of this episode's replies took (``latency_s``), replayed ones as recorded."""
        return self.episode_stats.samples()

    # One step ------------------------------------------------------------------------------------------------

    # An UnusableReply is deliberately none of the decisions Agent.act declares: the action loop ends the episode
    # as invalid_action for any other value, and records its text.
    def act(  # type: ignore[override]
            self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | UnusableReply | None:
        if self.turns and self.turns[-1].result is None and isinstance(self.turns[-1].decision, ActionCall):
            self.turns[-1].result = observation.last_result
        if self.answered:
            self.record.write("decision", decision="stop", why="answered")
            return None
        messages = [{"role": "system", "content": self.system},
                    {"role": "user", "content": self._step_content(instruction, observation)}]
        ids = [o.id for o in getattr(observation.scene, "objects", []) or []]
        schema = decision_schema(self.view, ids) if self.schema else None
        tries = 0
        while True:
            tries += 1
            reply = self.endpoint.ask(messages, schema, self.episode_stats, self.record,
                                      episode=f"{self.episode}, step {observation.step + 1}")
            try:
                return self._decided(parse_reply(reply.text, self.view, ids))
            except ReplyError as e:
                error, kind = str(e), e.kind
            self.episode_stats.parse_failures += 1
            self.record.write("unusable", error=error, tries=tries)
            if tries > self.max_retries:
                self.episode_stats.invalid_end = 1
                return UnusableReply(kind, error, tries)
            self.episode_stats.reasks += 1
            messages += [{"role": "assistant", "content": reply.text},
                         {"role": "user", "content": self.retry_template.render(error=error)}]

    def _decided(self, decision: ActionCall | Answer | None) -> ActionCall | Answer | None:
        self.episode_stats.decisions += 1
        self.record.write("decision", decision=None if decision is None else
                          (str(decision) if isinstance(decision, ActionCall) else {"answer": decision.value}))
        if decision is not None:
            self.turns.append(Turn(decision))
        self.answered = isinstance(decision, Answer)
        return decision

    def _step_content(self, instruction: Instruction, observation: Observation) -> Any:
        text = self.step_template.render(
            instruction=instruction.instruction, program=program_text(instruction), scene=scene_text(observation),
            history=history_text(self.turns, self.history), last_result=result_text(observation.last_result),
            step=str(observation.step + 1))
        send = self.images is ImagePolicy.always or (
            self.images is ImagePolicy.auto and self.view != ObservationMode.graph)
        if send and observation.images:
            return [{"type": "text", "text": text}, *image_parts(observation)]
        return text
