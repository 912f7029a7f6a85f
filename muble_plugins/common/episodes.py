"""Symbolic roll-outs: an agent played against the symbolic world through the core action loop.

Ground-truth plans come from it, and it tests agents without physics.
"""
from __future__ import annotations

from muble import Agent, Instruction, SceneGraph
from muble.episode import DEFAULT_MAX_STEPS, EpisodeResult, run_episode

from muble_plugins.common.success import check
from muble_plugins.common.symbolic import SymbolicWorld

__all__ = ["run_symbolic_episode"]


def run_symbolic_episode(instruction: Instruction, scene: SceneGraph, agent: Agent,
                         max_steps: int = DEFAULT_MAX_STEPS) -> EpisodeResult:
    """Play ``agent`` on ``instruction`` in a symbolic copy of ``scene`` and judge the outcome."""
    return run_episode(instruction, SymbolicWorld(scene), agent, check, max_steps=max_steps)
