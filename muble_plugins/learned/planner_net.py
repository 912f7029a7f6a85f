"""The planner network (PyTorch; imported only when a planner is trained or loaded).

Token features (``planner_features``) are embedded linearly and mixed by a Transformer encoder without positional
encoding (a scene's objects have no order; where order matters, e.g. a stack, it is a feature). The goal token's
output gives the primitive class; a pointer scores every token against a query made of the goal token's output and
the chosen class, over the tokens that class may name.
"""
from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

from muble.core.types import TABLE_PARTS
from muble_plugins.learned.planner_features import CLASSES, FEATURE_DIM, IGNORE, TARGET_KINDS, target_mask

NEG = -1e9


class PlannerNet(nn.Module):
    def __init__(self, in_dim: int = FEATURE_DIM, width: int = 32, heads: int = 2, layers: int = 2,
                 classes: int = len(CLASSES)):
        super().__init__()
        self.width = width
        self.embed = nn.Linear(in_dim, width)
        layer = nn.TransformerEncoderLayer(width, heads, dim_feedforward=4 * width, dropout=0.0, batch_first=True)
        self.encoder = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.classify = nn.Linear(width, classes)
        self.class_embed = nn.Embedding(classes, width)
        self.query = nn.Linear(width, width)
        self.key = nn.Linear(width, width)

    def forward(self, x: torch.Tensor, pad: torch.Tensor, cls: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``x`` (B, T, F) tokens, ``pad`` (B, T) True where padding, ``cls`` (B,) the class the pointer is for.
        Returns class logits (B, C) and pointer logits (B, T) (before the class's target mask)."""
        h = self.encoder(self.embed(x), src_key_padding_mask=pad)
        return self.classify(h[:, 0]), self.point(h, pad, cls)

    def point(self, h: torch.Tensor, pad: torch.Tensor, cls: torch.Tensor) -> torch.Tensor:
        q = self.query(h[:, 0]) + self.class_embed(cls)
        scores = torch.einsum("bd,btd->bt", q, self.key(h)) / math.sqrt(self.width)
        return scores.masked_fill(pad, NEG)


def batch(samples: list[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Pad token arrays to one length: (x, pad mask, per-class target masks (B, C, T))."""
    length = max(len(s) for s in samples)
    x = np.zeros((len(samples), length, FEATURE_DIM), dtype=np.float32)
    pad = np.ones((len(samples), length), dtype=bool)
    allowed = np.zeros((len(samples), len(CLASSES), length), dtype=bool)
    for b, s in enumerate(samples):
        x[b, :len(s)] = s
        pad[b, :len(s)] = False
        allowed[b, :, :len(s)] = _mask(len(s))
    return torch.from_numpy(x), torch.from_numpy(pad), torch.from_numpy(allowed)


_MASKS: dict[int, np.ndarray] = {}


def _mask(tokens: int) -> np.ndarray:
    if tokens not in _MASKS:
        _MASKS[tokens] = target_mask(tokens - len(TABLE_PARTS) - 2)  # less the goal, part and none tokens
    return _MASKS[tokens]


def loss_and_hits(net: PlannerNet, x, pad, allowed, y_cls, y_ptr) -> tuple[torch.Tensor, torch.Tensor]:
    """Cross-entropy of class and pointer (pointer with the labelled class, teacher forcing); per-sample hits
    (class right and, where there is a target, pointer right under the predicted class)."""
    logits, scores = net(x, pad, y_cls)
    mask = allowed[torch.arange(len(y_cls)), y_cls]
    scores = scores.masked_fill(~mask, NEG)
    loss = nn.functional.cross_entropy(logits, y_cls)
    has_target = y_ptr != IGNORE
    if has_target.any():
        loss = loss + nn.functional.cross_entropy(scores[has_target], y_ptr[has_target])
    with torch.no_grad():
        hits = (logits.argmax(1) == y_cls) & (~has_target | (scores.argmax(1) == y_ptr))
    return loss, hits


@torch.no_grad()
def decide(net: PlannerNet, tokens: np.ndarray) -> tuple[int, int]:
    """The argmax class and, for a class with a target, the argmax pointer among the tokens it may name."""
    x, pad, allowed = batch([tokens])
    h = net.encoder(net.embed(x), src_key_padding_mask=pad)
    cls = int(net.classify(h[:, 0]).argmax(1))
    if CLASSES[cls] not in TARGET_KINDS:
        return cls, IGNORE
    scores = net.point(h, pad, torch.tensor([cls]))
    scores = scores.masked_fill(~allowed[:, cls], NEG)
    return cls, int(scores.argmax(1))
