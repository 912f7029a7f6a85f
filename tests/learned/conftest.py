"""Shared fixtures of the learned parts' tests."""
from __future__ import annotations

import pytest


@pytest.fixture
def stop_at_next_checkpoint(monkeypatch):
    """A function that makes training runs stop as a Ctrl-C would, right after they write a checkpoint; it
    returns the function that lets later runs go on normally."""
    from muble_plugins.learned import checkpoint as ckpt

    real_save = ckpt.save

    def save_then_stop(*args, **kwargs):
        real_save(*args, **kwargs)
        raise KeyboardInterrupt

    def arm():
        monkeypatch.setattr(ckpt, "save", save_then_stop)
        return lambda: monkeypatch.setattr(ckpt, "save", real_save)

    return arm
