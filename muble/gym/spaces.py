"""Gymnasium spaces shared by the MuBlE environments: JSON text and camera images."""
from __future__ import annotations

import json
from typing import Any

import numpy as np
from gymnasium import spaces

# Printable ASCII: what ``json.dumps(..., ensure_ascii=True)`` writes, and what instruction text is kept to.
TEXT_CHARSET = "".join(chr(c) for c in range(32, 127))


def text_space(max_length: int) -> spaces.Text:
    return spaces.Text(max_length=max_length, min_length=0, charset=TEXT_CHARSET)


def as_text(value: str, max_length: int, what: str) -> str:
    """``value`` in the text charset (other characters escaped), or a ValueError if it is longer than allowed."""
    text = value.encode("ascii", "backslashreplace").decode("ascii")
    text = "".join(c if c in TEXT_CHARSET else f"\\x{ord(c):02x}" for c in text)
    if len(text) > max_length:
        raise ValueError(f"{what} has {len(text)} characters, more than the space's {max_length}; raise the "
                         "environment's max_text")
    return text


def json_text(value: Any, max_length: int, what: str) -> str:
    return as_text(json.dumps(value, ensure_ascii=True, separators=(",", ":"), allow_nan=False), max_length, what)


def image_space(height: int, width: int) -> spaces.Box:
    return spaces.Box(0, 255, shape=(int(height), int(width), 3), dtype=np.uint8)
