"""What ``muble train`` hands a trainer (``muble.core.interfaces.Trainer``): where to write, which seed, and what
every checkpoint must record."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class TrainingRun:
    """One training run of one part.

    ``out_dir`` holds the run's checkpoints and figures; ``seed`` decides the data it builds and its training
    (same seed, same checkpoint); ``resume`` continues from the last checkpoint in ``out_dir`` (one recorded under
    another config is refused); ``record`` is what every checkpoint stores beside the weights: the composed
    config, the seeds, the package versions and the code revision (``muble.io.manifest.make_manifest``);
    ``progress`` shows a progress bar; ``protocol`` is the frozen protocol's settings for the training split
    (object pool, property ranges) or None; ``data_root`` a dataset folder written by ``muble generate`` for
    trainers that learn from rendered scenes (None: the trainer builds its own data).
    """

    out_dir: Path
    seed: int = 0
    resume: bool = True
    record: dict[str, Any] = field(default_factory=dict)
    progress: bool = True
    protocol: dict[str, Any] | None = None
    data_root: Path | None = None
    threads: int = 0  # CPU threads for training (0: the library's default)
