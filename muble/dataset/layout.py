"""Where each output of a SHOP-VRB2 dataset lives (the original release's layout, one folder per split)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

PREFIX = "SHOP_VRB2"


@dataclass(frozen=True)
class DatasetLayout:
    root: Path
    split: str

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
