"""Images side by side in a grid with captions: the contact sheets of ``muble render`` and renderer plugins."""
from __future__ import annotations

import math

import numpy as np

from muble.core.errors import ConfigError

SHEET_COLUMNS = 4
SHEET_THUMB_WIDTH = 320


def contact_sheet(images: list[np.ndarray], columns: int = SHEET_COLUMNS, width: int = SHEET_THUMB_WIDTH,
                  labels: list[str] | None = None) -> np.ndarray:
    """The images side by side in rows of ``columns``, each scaled to ``width`` pixels, with a caption."""
    from PIL import Image, ImageDraw

    if not images:
        raise ConfigError("a contact sheet needs at least one image")
    h, w = images[0].shape[:2]
    height = round(h * width / w)
    rows = math.ceil(len(images) / columns)
    cols = min(columns, len(images))
    sheet = Image.new("RGB", (cols * width + (cols + 1) * 4, rows * height + (rows + 1) * 4), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, image in enumerate(images):
        x, y = 4 + (i % columns) * (width + 4), 4 + (i // columns) * (height + 4)
        sheet.paste(Image.fromarray(image).resize((width, height), Image.Resampling.LANCZOS), (x, y))
        caption = labels[i] if labels else str(i)
        draw.rectangle([x, y, x + 8 * len(caption) + 6, y + 14], fill=(0, 0, 0))
        draw.text((x + 3, y + 1), caption, fill=(255, 255, 255))
    return np.asarray(sheet)
