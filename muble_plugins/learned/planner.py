"""``muble train trainer=planner``: the learned planner (NS-AP style), trained on the oracle's symbolic roll-outs.

**Data.** Scenes are sampled deterministically from the run's seed (``muble_plugins.common.synthetic``: symbolic
scenes of 3 to 6 objects of the SHOP-VRB2 object set, or of the protocol's training pool, as the object set draws
them); every SHOP-VRB2
template task writes an instruction for each scene it suits (``Task.generate``), and the built-in oracle
(``OracleAgent``, the task's ``next_actions``) plays it in the symbolic world through the core action loop. Every
state the agent side observes is labelled with the oracle's next decision (a primitive and its target, or stop).
With probability ``explore`` the roll-out takes a random primitive instead and the oracle labels the state it
leads to (DAgger-like), and with probability ``slip`` a primitive fails without effect, as a physical one may (a
grasp that misses, a move with no plan); so the planner also learns to recover from states the oracle never
visits on its own.

**Why symbolic roll-outs, not physics sequences.** The planner's decision depends only on the symbolic state
(the gripper flags, what is measured, where objects stand relative to the goal), which the symbolic and the
physical world report alike. A symbolic roll-out costs milliseconds; a physical scene costs about 16 CPU-seconds
to generate (docs/scene_generation.md) and each of its episodes about 14 CPU-seconds of physics (the oracle's 100
mini episodes: about 700 s on 2 cores), so the 2,000 scenes, ~14,000 episodes and ~250,000 labelled states of a
default run take CPU-minutes instead of some 60 CPU-hours, and exploration (which physics sequences of the oracle
would never contain) is free.

**Model and training.** ``planner_net.PlannerNet``: a Transformer encoder over a goal token, one token per object
and a token per table part (plus "none"), with a class head and a pointer (``planner_features`` documents the
tokens). Cross-entropy on class and pointer, Adam, deterministic from ``run.seed``; a checkpoint after every epoch
at ``OUT/planner.pt`` that a stopped run resumes from. Validation scenes come from a seed stream disjoint from the
training scenes'; the figures are data and training seconds, train and validation action accuracy, and the
planner's symbolic success per template on the validation instructions (arg-max decisions, no exploration).
"""
from __future__ import annotations

import dataclasses
import functools
import logging
import time
from typing import Any

import numpy as np

from muble import (ActionResult, Agent, Answer, Instruction, ObjectSet, Observation, ObservationMode, Outcome,
                   SceneGraph, Task, Track, get_registry)
from muble.core import streams
from muble.core.interfaces import Trainer
from muble.core.training import TrainingRun
from muble.episode import DEFAULT_MAX_STEPS, run_episode

from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.success import check
from muble_plugins.common.symbolic import SymbolicWorld
from muble_plugins.common.synthetic import keyed_scene, object_set
from muble.core.errors import ConfigError, unknown_name
from muble.core.ranges import configured

from muble_plugins.learned.config import TEMPLATES, PlannerTrainerConfig
from muble_plugins.learned.planner_features import (CLASSES, FEATURE_DIM, Memory, encode, features, known_view,
                                                    layout, random_call)

log = logging.getLogger(__name__)

# Primitives per roll-out: an episode's limit (the oracle needs at most about 30 on SHOP-VRB2, 46 on the physical
# family).
MAX_STEPS = DEFAULT_MAX_STEPS

# The training data's streams (muble.core.streams), each keyed by (part, scene index[, k]) with part 0 for the
# training scenes and 1 for the validation scenes: the scenes, their instructions and their roll-outs never share
# a stream (numpy's lists of entropy once made a scene's property draws its first roll-out's).
INSTRUCTION_STREAM = streams.declare("train.planner.instruction", "the instruction template k writes for a scene "
                                     "of the learned planner's data (part, scene index, k)")
ROLLOUT_STREAM = streams.declare("train.planner.rollout", "the explored primitives and simulated slips of the "
                                 "roll-out of instruction k of a scene (part, scene index, k)")
ORDER_STREAM = streams.declare("train.planner.order", "the order of the training samples in an epoch (epoch)")


def _part(validation: bool) -> int:
    return 1 if validation else 0


def scene_for(seed: int, index: int, validation: bool, objects: ObjectSet | None = None) -> SceneGraph:
    """Scene ``index`` of the training or the validation part: the synthetic scene of key ``(part, index)``
    (``muble_plugins.common.synthetic.keyed_scene``), so no validation scene is a training scene's draws, of
    ``objects`` (default: the SHOP-VRB2 object set; a protocol's run: its training pool)."""
    return keyed_scene(seed, (_part(validation), index), index, objects=objects)


def instructions_for(scene: SceneGraph, seed: int, index: int, validation: bool,
                     templates: tuple[str, ...] = TEMPLATES) -> list[Instruction]:
    """One instruction per template that suits ``scene`` (deterministic from the seed and the index)."""
    out = []
    for k, name in enumerate(templates):
        task = _task(name)
        out.extend(task.generate(scene, streams.stream(INSTRUCTION_STREAM, seed, _part(validation), index, k)))
    return out


@functools.cache
def _task(name: str) -> Task:
    return get_registry().create("task", name, {})


class _Oracle(OracleAgent):
    """The oracle, its view of the scene (measurements and flags filled in) built by ``known_view`` (the same
    bookkeeping, without deep copies of the scene) and kept for the features."""

    view: SceneGraph | None = None

    def _task(self, instruction: Instruction) -> Task:
        return _task(instruction.template_id)

    def _known(self, observation: Observation) -> Observation:
        self.view = known_view(observation, self.known, self.last)
        return dataclasses.replace(observation, scene=self.view)


class _SlippingWorld(SymbolicWorld):
    """The symbolic world, where a primitive fails without effect with probability ``slip``."""

    def __init__(self, scene: SceneGraph, rng: np.random.Generator, slip: float):
        super().__init__(scene)
        self.rng, self.slip = rng, slip

    def apply(self, call):
        if self.slip and self.rng.random() < self.slip:
            self.steps += 1
            return ActionResult(False, failure_reason=f"{call}: failed (simulated)")
        return super().apply(call)


class _Recorder(Agent):
    """Plays the oracle (or, with probability ``explore``, a random primitive) and records every observed state
    with the oracle's decision there."""

    def __init__(self, rng: np.random.Generator, explore: float):
        self.rng, self.explore = rng, explore
        self.oracle = _Oracle()
        self.memory = Memory()
        self.samples: list[tuple[np.ndarray, int, int]] = []

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        self.oracle.reset(instruction, observation, track=track, mode=mode)
        self.memory = Memory()

    def act(self, instruction: Instruction, observation: Observation):
        failed = self.memory.observe(observation)
        label = self.oracle.act(instruction, observation)
        scene = self.oracle.view
        tokens, _ = features(instruction.program, scene, self.memory.known, failed)
        cls, pointer = encode(label, scene)
        self.samples.append((tokens.astype(np.float16), cls, pointer))
        if label is None or isinstance(label, Answer):
            return label
        if self.explore and self.rng.random() < self.explore:
            label = random_call(self.rng, observation.scene)
            self.oracle.last = label
        self.memory.last = label
        return label


def rollouts(seed: int, indices: range, validation: bool, explore: float, slip: float, progress=None,
             templates: tuple[str, ...] = TEMPLATES, objects: ObjectSet | None = None
             ) -> tuple[list[tuple[np.ndarray, int, int]], list[tuple[Instruction, SceneGraph]]]:
    """Labelled states of the oracle's roll-outs on the scenes ``indices`` (of ``objects``: ``scene_for``), and
    the (instruction, scene) pairs."""
    samples: list[tuple[np.ndarray, int, int]] = []
    episodes: list[tuple[Instruction, SceneGraph]] = []
    items = progress(indices) if progress else indices
    quiet = logging.getLogger(OracleAgent.__module__)
    level = quiet.level
    quiet.setLevel(logging.WARNING)  # the oracle logs every failed primitive it retries: most explored ones
    try:
        for index in items:
            _scene_rollouts(seed, index, validation, explore, slip, samples, episodes, templates, objects)
    finally:
        quiet.setLevel(level)
    return samples, episodes


def _scene_rollouts(seed: int, index: int, validation: bool, explore: float, slip: float,
                    samples: list, episodes: list, templates: tuple[str, ...] = TEMPLATES,
                    objects: ObjectSet | None = None) -> None:
    scene = scene_for(seed, index, validation, objects)
    for k, instruction in enumerate(instructions_for(scene, seed, index, validation, templates)):
        episodes.append((instruction, scene))
        rng = streams.stream(ROLLOUT_STREAM, seed, _part(validation), index, k)
        recorder = _Recorder(rng, explore)
        world = _SlippingWorld(scene, rng, slip)
        run_episode(instruction, world, recorder, check, max_steps=MAX_STEPS)
        samples.extend(recorder.samples)


def symbolic_success(agent: Agent, episodes: list[tuple[Instruction, SceneGraph]]) -> dict[str, tuple[int, int]]:
    """(solved, episodes) per template of ``agent`` played in the symbolic world."""
    counts: dict[str, list[int]] = {}
    for instruction, scene in episodes:
        result = run_episode(instruction, SymbolicWorld(scene), agent, check, max_steps=MAX_STEPS)
        entry = counts.setdefault(instruction.template_id, [0, 0])
        entry[0] += result.outcome is Outcome.SUCCESS
        entry[1] += 1
    return {k: (v[0], v[1]) for k, v in sorted(counts.items())}


class PlannerTrainer(Trainer):
    """Trains ``planner_net.PlannerNet`` on symbolic roll-outs of the oracle (see the module doc)."""

    def __init__(self, config: PlannerTrainerConfig | None = None, **options):
        cfg = configured(PlannerTrainerConfig, config, options, owner="trainer 'planner'")
        self.settings = dataclasses.asdict(cfg)
        if cfg.width % cfg.heads:
            raise ConfigError(f"trainer.width={cfg.width} must be a multiple of trainer.heads={cfg.heads}")
        unknown = [t for t in cfg.templates if t not in get_registry().names("task")]
        if unknown:
            raise ConfigError(unknown_name("trainer.templates entry", unknown[0], get_registry().names("task")))
        self.templates = tuple(cfg.templates) or TEMPLATES

    def train(self, run: TrainingRun) -> dict[str, Any]:
        from muble_plugins.learned import checkpoint as ck

        torch = ck.torch_module()
        from muble_plugins.learned.planner_net import PlannerNet, batch, loss_and_hits

        s = self.settings
        ident = ck.identity(run, s)
        ck.set_threads(run)
        ck.seed_everything(run.seed)
        path = run.out_dir / "planner.pt"
        previous = ck.resume_from(path, "planner", run, ident)

        start, cpu = time.perf_counter(), time.process_time()

        def bar(items):
            return ck.progress(items, run, "roll-outs", total=len(items))

        # The objects of the protocol's training pool when the run has a protocol: no held-out model, finish or
        # property range of an evaluation split is in the data.
        objects = object_set(run.protocol)
        train_samples, _ = rollouts(run.seed, range(s["scenes"]), False, s["explore"], s["slip"], bar,
                                    self.templates, objects)
        val_samples, val_episodes = rollouts(run.seed, range(s["validation_scenes"]), True, s["explore"],
                                             s["slip"], bar, self.templates, objects)
        data_s, data_cpu_s = time.perf_counter() - start, time.process_time() - cpu

        model = {"in_dim": FEATURE_DIM, "width": s["width"], "heads": s["heads"], "layers": s["layers"],
                 "classes": len(CLASSES)}
        net = PlannerNet(**model)
        optimiser = torch.optim.Adam(net.parameters(), lr=s["learning_rate"])
        epoch0, history, train_s, train_cpu_s = 0, [], 0.0, 0.0
        if previous is not None:
            epoch0 = ck.restore(previous, net, optimiser)
            history = list(previous["extra"].get("history", []))
            train_s = float(previous["extra"].get("train_s", 0.0))
            train_cpu_s = float(previous["extra"].get("train_cpu_s", 0.0))
            log.info("resuming %s after epoch %d", path, epoch0)

        def tensors(samples, order):
            for b in range(0, len(order), s["batch_size"]):
                chunk = [samples[i] for i in order[b:b + s["batch_size"]]]
                x, pad, allowed = batch([c[0] for c in chunk])
                y_cls = torch.tensor([c[1] for c in chunk], dtype=torch.long)
                y_ptr = torch.tensor([c[2] for c in chunk], dtype=torch.long)
                yield x, pad, allowed, y_cls, y_ptr

        def accuracy(samples) -> float:
            if not samples:
                return float("nan")
            net.eval()
            hits = 0
            with torch.no_grad():
                for x, pad, allowed, y_cls, y_ptr in tensors(samples, range(len(samples))):
                    hits += int(loss_and_hits(net, x, pad, allowed, y_cls, y_ptr)[1].sum())
            return hits / len(samples)

        for epoch in range(epoch0, s["epochs"]):
            t, cpu = time.perf_counter(), time.process_time()
            net.train()
            order = torch.randperm(len(train_samples), generator=torch.Generator().manual_seed(
                streams.integer_seed(ORDER_STREAM, run.seed, epoch))).tolist()
            hits = total = 0
            loss_sum = 0.0
            steps = -(-len(order) // s["batch_size"])
            for x, pad, allowed, y_cls, y_ptr in ck.progress(tensors(train_samples, order), run,
                                                              f"epoch {epoch + 1}/{s['epochs']}", total=steps):
                loss, batch_hits = loss_and_hits(net, x, pad, allowed, y_cls, y_ptr)
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                hits += int(batch_hits.sum())
                total += len(y_cls)
                loss_sum += float(loss.detach()) * len(y_cls)
            train_s += time.perf_counter() - t
            train_cpu_s += time.process_time() - cpu
            entry = {"epoch": epoch + 1, "loss": loss_sum / max(total, 1), "train_accuracy": hits / max(total, 1),
                     "validation_accuracy": accuracy(val_samples)}
            history.append(entry)
            log.info("epoch %d: loss %.4f, train accuracy %.4f, validation accuracy %.4f", epoch + 1,
                     entry["loss"], entry["train_accuracy"], entry["validation_accuracy"])
            ck.save(path, "planner", run, ident, epoch + 1,
                    {"model": net.state_dict(), "optimiser": optimiser.state_dict(), "rng": ck.rng_states()},
                    {"model": model, "layout": layout(), "history": history, "train_s": train_s,
                     "train_cpu_s": train_cpu_s})

        net.eval()
        from muble_plugins.learned.agent import LearnedPlannerAgent

        start = time.perf_counter()
        success = symbolic_success(LearnedPlannerAgent(network=net), val_episodes)
        eval_s = time.perf_counter() - start
        solved = sum(v[0] for v in success.values())
        episodes = sum(v[1] for v in success.values())
        last = history[-1] if history else {}
        figures: dict[str, Any] = {
            "train_samples": len(train_samples), "validation_samples": len(val_samples),
            "data_s": round(data_s, 2), "train_s": round(train_s, 2), "symbolic_eval_s": round(eval_s, 2),
            # CPU seconds of this process: the cost on a machine others share, where wall time says little.
            "data_cpu_s": round(data_cpu_s, 2), "train_cpu_s": round(train_cpu_s, 2),
            "epochs": len(history), "loss": last.get("loss"),
            "train_accuracy": last.get("train_accuracy"), "validation_accuracy": last.get("validation_accuracy"),
            "validation_episodes": episodes,
            "symbolic_success": solved / episodes if episodes else float("nan"),
            **{f"symbolic_success/{k}": f"{v[0]}/{v[1]}" for k, v in success.items()},
        }
        payload = ck.load(path, "planner")
        ck.save(path, "planner", run, ident, payload["epoch"], payload["state"],
                {**payload["extra"], "figures": figures})
        return figures


__all__ = ["PlannerTrainer", "TEMPLATES", "instructions_for", "rollouts", "scene_for", "symbolic_success"]
