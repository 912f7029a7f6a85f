"""Where each output of a SHOP-VRB2 dataset lives (the original release's layout, one folder per split)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from muble.core.errors import ConfigError

PREFIX = "SHOP_VRB2"

# A split name is one folder name: letters, digits, '_', '-' and '.', not starting with '.' (so never '..').
SPLIT_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


def check_split_name(name: object, what: str = "dataset.splits") -> str:
    """``name`` if it is a valid split name, else a ``ConfigError``: a split is a folder under the dataset root,
    so a path separator or ``..`` would write outside it."""
    if not isinstance(name, str) or not SPLIT_NAME.fullmatch(name):
        raise ConfigError(f"{what}: invalid split name {name!r}; a split name is one folder name of letters, "
                          "digits, '_', '-' and '.' (not starting with '.', no '/' or '..'), e.g. train, val, test")
    return name


@dataclass(frozen=True)
class DatasetLayout:
    root: Path
    split: str

    def __post_init__(self) -> None:
        check_split_name(self.split)

    def stem(self, index: int) -> str:
        return f"{PREFIX}_{self.split}_{index:06d}"

    @property
    def split_dir(self) -> Path:
        return self.root / self.split

    def image(self, index: int) -> str:
        return f"images/{self.stem(index)}.png"

    def scene(self, index: int) -> str:
        return f"scenes/{self.stem(index)}.json"

    def instruction(self, index: int) -> str:
        """Written last for an index: its presence marks the index complete."""
        return f"instructions/{self.stem(index)}.json"

    def combined_scenes(self) -> str:
        return f"{PREFIX}_{self.split}_scenes.json"

    def combined_instructions(self) -> str:
        return f"{PREFIX}_{self.split}_instructions.json"
