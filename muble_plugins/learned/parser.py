"""The instruction parser: instruction text to the agent-side program, a small sequence-to-sequence Transformer.

Data: (instruction, program) pairs generated for the run's seed. Each scene is a synthetic scene
(``muble_plugins.common.synthetic``) of an object set through the registry (``trainer.object_set``: SHOP-VRB2's by
default, the protocol's training pool when the run has one), so names, colours (``metallic`` included), materials,
shapes and sizes are those of generated datasets. Every one of the ten SHOP-VRB2 template tasks then
writes its instruction for the scene (``Task.generate``); the target is ``agent_program`` of its program: each
step's type and words, nothing computed on the ground truth. Validation scenes come from a stream of their own,
disjoint from the training scenes.

Tokens: the text is lower-cased and split into words (``medium-sized`` is one) and punctuation; a word the
training data never had is ``<unk>``. The program is one token per step, its type and value together
(``filter_shape|"hemisphere"``, ``scene``), so a value of several words (``food box``, ``irregularly shaped``)
needs no more decoding steps than one of one word. Repeated pairs are kept: how often an instruction comes up is
part of what is learnt (kept once each, the few instructions that are most common in generated data, such as
"Measure the weight of the glass.", were outweighed by the many where "glass" is the material). The model is an
encoder-decoder Transformer (pre-norm, learned positions) decoded greedily; it never sees the instruction's
template id.

    muble train trainer=parser train.out_dir=runs/parser               # train (resumes into the same folder)
    python -m muble_plugins.learned.parser runs/parser/parser.pt DATA/test/SHOP_VRB2_test_instructions.json

The second line scores a checkpoint on an instruction file: exact match of the parse with ``agent_program`` of
each record's program, overall and per template.

PyTorch is imported inside functions only, so importing this module for the registry costs nothing.
"""
from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from muble.core import streams
from muble.core.errors import ConfigError
from muble.core.observation import agent_program
from muble.core.ranges import configured
from muble_plugins.learned import checkpoint as ckpt
from muble_plugins.learned.config import TEMPLATES, ParserTrainerConfig

KIND = "parser"
FILE_NAME = "parser.pt"
PAD, UNK, BOS, EOS = "<pad>", "<unk>", "<bos>", "<eos>"
SPECIALS = (PAD, UNK, BOS, EOS)
STEP_PREFIX, VALUE_SEPARATOR = "S:", "|"
MAX_POSITIONS = 64  # longest token sequence (text or program) the model has positions for
OBJECTS_PER_SCENE = (3, 7)  # inclusive: the protocol's scenes have 4 or 5, its long-horizon split 6 or 7
_WORD = re.compile(r"[a-z0-9]+(?:[-'][a-z0-9]+)*|[^\sa-z0-9]")
# The training data's streams (muble.core.streams): a scene's and each of its instructions' apart (numpy's lists of
# entropy once made a scene's stream its first instruction's), keyed by (part: 0 training, 1 validation, scene
# index[, template k]).
SCENE_STREAM = streams.declare("train.parser.scene", "a scene of the parser's data: its layout and objects drawn "
                               "from the object set (part, scene index)")
INSTRUCTION_STREAM = streams.declare("train.parser.instruction", "the instruction template k writes for a scene of "
                                     "the parser's data (part, scene index, k)")
ORDER_STREAM = streams.declare("train.parser.order", "the order of the training pairs in an epoch (epoch)")


# --- tokens -------------------------------------------------------------------------------------------------------

def tokenize(text: str) -> list[str]:
    """Lower-cased words (hyphenated ones whole) and punctuation marks."""
    return _WORD.findall(str(text).lower())


def program_tokens(program: Sequence[dict]) -> list[str]:
    """One token per step: its type, and its value (JSON, so any value survives the round trip) if it has one."""
    tokens = []
    for step in program:
        token = STEP_PREFIX + str(step["type"])
        if step.get("input_value") is not None:
            token += VALUE_SEPARATOR + json.dumps(step["input_value"], sort_keys=True)
        tokens.append(token)
    return tokens


def program_from_tokens(tokens: Iterable[str], keyless: Iterable[str] = ()) -> list[dict]:
    """The agent-side program the step tokens spell (anything else is skipped). ``keyless``: step types whose steps
    carry no ``input_value`` key when they have no value."""
    keyless = set(keyless)
    program: list[dict] = []
    for token in tokens:
        if not token.startswith(STEP_PREFIX):
            continue
        kind, _, value = token[len(STEP_PREFIX):].partition(VALUE_SEPARATOR)
        step: dict[str, Any] = {"input": None, "type": kind}
        if value:
            step["input_value"] = json.loads(value)
        elif kind not in keyless:
            step["input_value"] = None
        program.append(step)
    return program


class Vocabulary:
    def __init__(self, tokens: Iterable[str]):
        self.tokens = list(SPECIALS) + sorted(set(tokens) - set(SPECIALS))
        self.index = {t: i for i, t in enumerate(self.tokens)}

    @classmethod
    def of(cls, stored: list[str]) -> "Vocabulary":
        vocab = cls(())
        vocab.tokens, vocab.index = list(stored), {t: i for i, t in enumerate(stored)}
        return vocab

    def encode(self, tokens: Iterable[str]) -> list[int]:
        unk = self.index[UNK]
        return [self.index.get(t, unk) for t in tokens]

    def __len__(self) -> int:
        return len(self.tokens)


# --- data ---------------------------------------------------------------------------------------------------------

def template_names() -> list[str]:
    """The ten SHOP-VRB2 templates, in their overall order."""
    return list(TEMPLATES)


def object_set(protocol: dict | None = None, name: str = "shopvrb2"):
    """The object set ``name`` as ``muble generate`` samples it: with a protocol, its training split's pool
    (``muble_plugins.common.synthetic.object_set``)."""
    from muble_plugins.common import synthetic

    return synthetic.object_set(protocol, name)


def sample_scene(objects, rng: np.random.Generator, index: int):
    """A symbolic scene of ``objects`` (``muble_plugins.common.synthetic.sample_scene``): the set's attribute
    words, weights, stiffnesses, extents and affordances, laid out as the scene generator lays them out."""
    from muble_plugins.common import synthetic

    return synthetic.sample_scene(rng, index, n_objects=OBJECTS_PER_SCENE, objects=objects)


def build_pairs(seed: int, stream: int, scenes: int, protocol: dict | None = None,
                progress=lambda items, desc, total: items,
                objects_name: str = "shopvrb2") -> list[tuple[str, list[dict]]]:
    """(instruction text, agent-side program) for every template that suits each of ``scenes`` scenes; scene
    ``i`` of ``stream`` is deterministic from ``(seed, stream, i)`` (streams give disjoint scenes)."""
    from muble.plugins.registry import get_registry

    registry = get_registry()
    tasks = [registry.create("task", name, {}) for name in template_names()]
    objects = object_set(protocol, objects_name)
    pairs = []
    for i in progress(range(scenes), f"parser data ({'train' if stream == 0 else 'validation'})", scenes):
        scene = sample_scene(objects, streams.stream(SCENE_STREAM, seed, stream, i), i)
        for k, task in enumerate(tasks):
            for instruction in task.generate(scene, streams.stream(INSTRUCTION_STREAM, seed, stream, i, k)):
                pairs.append((instruction.instruction, agent_program(instruction.program)))
    return pairs


# --- model --------------------------------------------------------------------------------------------------------

def _model(architecture: dict[str, int]):
    """The encoder-decoder Transformer (a torch module) an architecture dict describes."""
    torch = ckpt.torch_module()
    nn = torch.nn

    class Seq2Seq(nn.Module):
        def __init__(self, source: int, target: int, width: int, heads: int, layers: int, feedforward: int,
                     positions: int, dropout: float):
            super().__init__()
            self.width = width
            self.source_embedding = nn.Embedding(source, width, padding_idx=0)
            self.target_embedding = nn.Embedding(target, width, padding_idx=0)
            self.source_position = nn.Embedding(positions, width)
            self.target_position = nn.Embedding(positions, width)
            encoder_layer = nn.TransformerEncoderLayer(width, heads, feedforward, dropout, batch_first=True,
                                                       norm_first=True)
            decoder_layer = nn.TransformerDecoderLayer(width, heads, feedforward, dropout, batch_first=True,
                                                       norm_first=True)
            self.encoder = nn.TransformerEncoder(encoder_layer, layers, norm=nn.LayerNorm(width),
                                                 enable_nested_tensor=False)
            self.decoder = nn.TransformerDecoder(decoder_layer, layers, norm=nn.LayerNorm(width))
            self.output = nn.Linear(width, target)

        def encode(self, source):
            positions = torch.arange(source.shape[1], device=source.device)
            x = self.source_embedding(source) + self.source_position(positions)
            return self.encoder(x, src_key_padding_mask=source == 0)

        def decode(self, target, memory, source_padding):
            n = target.shape[1]
            positions = torch.arange(n, device=target.device)
            y = self.target_embedding(target) + self.target_position(positions)
            causal = torch.triu(torch.ones(n, n, dtype=torch.bool, device=target.device), diagonal=1)
            h = self.decoder(y, memory, tgt_mask=causal, tgt_key_padding_mask=target == 0,
                             memory_key_padding_mask=source_padding)
            return self.output(h)

        def forward(self, source, target):
            return self.decode(target, self.encode(source), source == 0)

    return Seq2Seq(**architecture)


def _pad(rows: list[list[int]], length: int | None = None):
    torch = ckpt.torch_module()
    length = length or max(len(r) for r in rows)
    out = torch.zeros(len(rows), length, dtype=torch.long)
    for i, r in enumerate(rows):
        out[i, :len(r)] = torch.tensor(r[:length], dtype=torch.long)
    return out


def _greedy(model, sources: list[list[int]], bos: int, eos: int, max_steps: int) -> list[list[int]]:
    """Greedy decoding of a batch: the target ids of each source, without ``<bos>`` and ``<eos>``."""
    torch = ckpt.torch_module()
    source = _pad(sources)
    with torch.inference_mode():
        memory = model.encode(source)
        padding = source == 0
        out = torch.full((len(sources), 1), bos, dtype=torch.long)
        done = torch.zeros(len(sources), dtype=torch.bool)
        for _ in range(max_steps):
            nxt = model.decode(out, memory, padding)[:, -1].argmax(-1)
            nxt = torch.where(done, torch.zeros_like(nxt), nxt)  # finished rows get padding
            out = torch.cat([out, nxt[:, None]], dim=1)
            done |= nxt == eos
            if bool(done.all()):
                break
    results = []
    for row in out[:, 1:].tolist():
        results.append(row[:row.index(eos)] if eos in row else [t for t in row if t != 0])
    return results


# --- the parser an agent uses -------------------------------------------------------------------------------------

class InstructionParser:
    """A trained parser: ``InstructionParser.load(path).parse(text)`` gives the agent-side program."""

    def __init__(self, model, source: Vocabulary, target: Vocabulary, keyless: Iterable[str] = (),
                 max_steps: int = MAX_POSITIONS - 1):
        self.model = model.eval()
        self.source, self.target = source, target
        self.keyless = set(keyless)
        self.max_steps = max_steps

    @classmethod
    def load(cls, path: str | Path) -> "InstructionParser":
        """The parser in a checkpoint ``muble train trainer=parser`` wrote; ``ConfigError`` for any other file."""
        payload = ckpt.load(path, KIND)
        try:
            extra = payload["extra"]
            model = _model(extra["architecture"])
            model.load_state_dict(payload["state"]["model"])
            return cls(model, Vocabulary.of(extra["source_vocabulary"]), Vocabulary.of(extra["target_vocabulary"]),
                       extra.get("keyless_types", ()), int(extra.get("max_steps", MAX_POSITIONS - 1)))
        except (KeyError, TypeError, ValueError, RuntimeError) as e:
            raise ConfigError(f"'{path}' is a parser checkpoint this version cannot read "
                              f"({type(e).__name__}: {e}); train it again with `muble train trainer=parser`") from e

    def _source_ids(self, text: str) -> list[int]:
        ids = self.source.encode(tokenize(text if isinstance(text, str) else ""))[:MAX_POSITIONS]
        return ids or [self.source.index[UNK]]

    def parse(self, text: str) -> list[dict]:
        """The program of ``text``: ``[{"input": None, "type": ..., "input_value": ...}, ...]``. Unknown words
        are ``<unk>``; whatever the text, the answer is a list (possibly not the intended program)."""
        return self.parse_many([text])[0]

    def parse_many(self, texts: Sequence[str], batch_size: int = 256) -> list[list[dict]]:
        out = []
        bos, eos = self.target.index[BOS], self.target.index[EOS]
        for start in range(0, len(texts), batch_size):
            sources = [self._source_ids(t) for t in texts[start:start + batch_size]]
            for ids in _greedy(self.model, sources, bos, eos, self.max_steps):
                out.append(program_from_tokens((self.target.tokens[i] for i in ids), self.keyless))
        return out


def exact_match(parser: InstructionParser, pairs: Sequence[tuple[str, list[dict]]]) -> float:
    if not pairs:
        return float("nan")
    parsed = parser.parse_many([text for text, _ in pairs])
    return sum(p == program for p, (_, program) in zip(parsed, pairs)) / len(pairs)


# --- training -----------------------------------------------------------------------------------------------------

class ParserTrainer:
    """``muble train trainer=parser`` (settings: ``muble_plugins.learned.config.ParserTrainerConfig``)."""

    def __init__(self, config: ParserTrainerConfig | None = None, **options: Any):
        self.config = cfg = configured(ParserTrainerConfig, config, options, owner="trainer 'parser'")
        if cfg.width % cfg.heads:
            raise ConfigError(f"trainer.width={cfg.width} must be a multiple of trainer.heads={cfg.heads}")
        self.settings = {"scenes": cfg.scenes, "epochs": cfg.epochs, "batch_size": cfg.batch_size,
                         "learning_rate": cfg.learning_rate, "width": cfg.width, "heads": cfg.heads,
                         "layers": cfg.layers, "validation_scenes": cfg.validation_scenes,
                         "feedforward": cfg.feedforward, "dropout": cfg.dropout}
        # Kept out at its default, so checkpoints made before the setting still resume.
        if cfg.object_set != ParserTrainerConfig.object_set:
            self.settings["object_set"] = cfg.object_set

    def train(self, run) -> dict[str, Any]:
        torch = ckpt.torch_module()
        s = self.settings
        ckpt.seed_everything(run.seed)
        ckpt.set_threads(run)
        path = Path(run.out_dir) / FILE_NAME
        ident = ckpt.identity(run, dict(s))
        resumed = ckpt.resume_from(path, KIND, run, ident)

        def bar(items, desc, total):
            return ckpt.progress(items, run, desc, total)

        t0 = time.perf_counter()
        objects_name = self.config.object_set
        train_pairs = build_pairs(run.seed, 0, s["scenes"], run.protocol, bar, objects_name)
        validation_pairs = build_pairs(run.seed, 1, s["validation_scenes"], run.protocol, bar, objects_name)
        data_seconds = time.perf_counter() - t0

        source = Vocabulary(w for text, _ in train_pairs for w in tokenize(text))
        target = Vocabulary(t for _, program in train_pairs for t in program_tokens(program))
        keyless = sorted({step["type"] for _, program in train_pairs for step in program
                          if "input_value" not in step})
        sources = [source.encode(tokenize(text))[:MAX_POSITIONS] for text, _ in train_pairs]
        bos, eos = target.index[BOS], target.index[EOS]
        targets = [[bos, *target.encode(program_tokens(p)), eos][:MAX_POSITIONS] for _, p in train_pairs]
        max_steps = min(MAX_POSITIONS - 1, max(len(t) for t in targets) + 4)
        architecture = {"source": len(source), "target": len(target), "width": s["width"], "heads": s["heads"],
                        "layers": s["layers"], "feedforward": s["feedforward"], "positions": MAX_POSITIONS,
                        "dropout": s["dropout"]}
        model = _model(architecture)
        optimiser = torch.optim.AdamW(model.parameters(), lr=s["learning_rate"], weight_decay=0.01)
        batches_per_epoch = math.ceil(len(sources) / s["batch_size"])
        total_steps = batches_per_epoch * s["epochs"]
        warmup = min(200, max(1, total_steps // 10))
        schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, lambda step: min(
            (step + 1) / warmup, 0.5 * (1 + math.cos(math.pi * min(1.0, step / max(1, total_steps))))))
        start_epoch, losses, train_seconds = 0, [], 0.0
        if resumed is not None:
            start_epoch = ckpt.restore(resumed, model, optimiser, schedule)
            losses = list(resumed["extra"].get("losses", []))
            train_seconds = float(resumed["extra"].get("train_seconds", 0.0))

        loss_fn = torch.nn.CrossEntropyLoss(ignore_index=0)
        extra = {"source_vocabulary": source.tokens, "target_vocabulary": target.tokens,
                 "architecture": architecture, "keyless_types": keyless, "max_steps": max_steps}
        for epoch in range(start_epoch, s["epochs"]):
            t1 = time.perf_counter()
            model.train()
            order = streams.stream(ORDER_STREAM, run.seed, epoch).permutation(len(sources))
            total, count = 0.0, 0
            for b in bar(range(batches_per_epoch), f"parser epoch {epoch + 1}/{s['epochs']}", batches_per_epoch):
                rows = order[b * s["batch_size"]:(b + 1) * s["batch_size"]]
                src = _pad([sources[i] for i in rows])
                tgt = _pad([targets[i] for i in rows])
                logits = model(src, tgt[:, :-1])
                loss = loss_fn(logits.reshape(-1, logits.shape[-1]), tgt[:, 1:].reshape(-1))
                optimiser.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
                optimiser.step()
                schedule.step()
                total, count = total + loss.detach().item() * len(rows), count + len(rows)
            losses.append(total / max(1, count))
            train_seconds += time.perf_counter() - t1
            state = {"model": model.state_dict(), "optimiser": optimiser.state_dict(),
                     "schedule": schedule.state_dict(), "rng": ckpt.rng_states()}
            ckpt.save(path, KIND, run, ident, epoch + 1, state,
                      {**extra, "losses": losses, "train_seconds": train_seconds})

        parser = InstructionParser(model, source, target, keyless, max_steps)
        figures = {"data_seconds": round(data_seconds, 2), "train_seconds": round(train_seconds, 2),
                   "train_pairs": len(train_pairs), "validation_pairs": len(validation_pairs),
                   "validation_exact_match": exact_match(parser, validation_pairs),
                   "final_loss": losses[-1] if losses else float("nan"), "checkpoint": str(path)}
        if resumed is None or start_epoch < s["epochs"]:
            payload = ckpt.load(path, KIND)
            ckpt.save(path, KIND, run, ident, payload["epoch"], payload["state"], {**payload["extra"],
                                                                                   "figures": figures})
        return figures


# --- scoring an instruction file ----------------------------------------------------------------------------------

def score_file(parser: InstructionParser, path: str | Path) -> dict[str, Any]:
    """Exact match of ``parser`` on an instruction file (``agent_program`` of each record's program), overall and
    per template, and up to ten of the misses."""
    records = json.loads(Path(path).read_text())["instructions"]
    parsed = parser.parse_many([r["instruction"] for r in records])
    per: dict[str, list[int]] = {}
    misses = []
    for record, program in zip(records, parsed):
        hit = program == agent_program(record["program"])
        per.setdefault(record.get("template_id", "?"), []).append(int(hit))
        if not hit and len(misses) < 10:
            misses.append({"instruction": record["instruction"], "parsed": program_tokens(program),
                           "expected": program_tokens(agent_program(record["program"]))})
    hits = sum(sum(v) for v in per.values())
    return {"file": str(path), "instructions": len(records), "exact_match": hits / max(1, len(records)),
            "per_template": {k: f"{sum(v)}/{len(v)}" for k, v in sorted(per.items())}, "misses": misses}


def main(argv: Sequence[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m muble_plugins.learned.parser",
                                 description="exact match of a parser checkpoint on instruction files")
    ap.add_argument("checkpoint")
    ap.add_argument("instructions", nargs="+", help="SHOP_VRB2_<split>_instructions.json files")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)
    ckpt.torch_module().set_num_threads(args.threads)
    parser = InstructionParser.load(args.checkpoint)
    for path in args.instructions:
        print(json.dumps(score_file(parser, path), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
