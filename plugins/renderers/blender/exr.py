"""A reader for the uncompressed, scan-line OpenEXR files that Blender writes for its render passes.

Blender's Python module cannot hand render passes to Python directly in background mode, so every pass of a
render is written to one multilayer EXR (codec ``NONE``) and read back here with numpy. Only what Blender
writes is supported: a single part, scan lines, no compression, HALF/FLOAT/UINT channels.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from muble.core.errors import RenderError

_MAGIC = 20000630
_PIXEL_TYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


def _read_cstring(buf: bytes, pos: int) -> tuple[str, int]:
    end = buf.index(b"\0", pos)
    return buf[pos:end].decode("ascii"), end + 1


def _channel_list(value: bytes) -> list[tuple[str, int]]:
    channels, pos = [], 0
    while value[pos] != 0:
        name, pos = _read_cstring(value, pos)
        pixel_type, _linear, xs, ys = struct.unpack_from("<iB3xii", value, pos)
        pos += 16
        if xs != 1 or ys != 1:
            raise RenderError(f"EXR channel '{name}' is subsampled ({xs}x{ys}); render passes never are")
        channels.append((name, pixel_type))
    return channels


def read_exr(path: str | Path) -> dict[str, np.ndarray]:
    """All channels of an uncompressed EXR as float32 or uint32 arrays of shape (height, width), top row first."""
    buf = Path(path).read_bytes()
    magic, version = struct.unpack_from("<ii", buf, 0)
    if magic != _MAGIC:
        raise RenderError(f"{path} is not an OpenEXR file")
    if version & 0x1200:  # tiled (0x200) or multi-part (0x1000)
        raise RenderError(f"{path} is tiled or multi-part; write render passes as scan lines, single part")
    pos, attrs = 8, {}
    while buf[pos] != 0:
        name, pos = _read_cstring(buf, pos)
        _type, pos = _read_cstring(buf, pos)
        (size,) = struct.unpack_from("<i", buf, pos)
        pos += 4
        attrs[name] = buf[pos:pos + size]
        pos += size
    pos += 1
    if attrs["compression"][0] != 0:
        raise RenderError(f"{path} is compressed (codec {attrs['compression'][0]}); set exr_codec='NONE'")
    xmin, ymin, xmax, ymax = struct.unpack("<iiii", attrs["dataWindow"])
    width, height = xmax - xmin + 1, ymax - ymin + 1
    channels = _channel_list(attrs["channels"])
    # One scan line per chunk when uncompressed; each holds every channel's row, in channel-list order.
    row = np.dtype([(name, _PIXEL_TYPES[ptype], (width,)) for name, ptype in channels])
    offsets = np.frombuffer(buf, dtype="<u8", count=height, offset=pos)
    chunk = np.dtype([("y", "<i4"), ("size", "<i4"), ("row", row)])
    first = int(offsets[0])
    if np.all(np.diff(offsets.astype(np.int64)) == chunk.itemsize):
        # Chunks are contiguous: read them all in one strided view (the common case).
        chunks = np.frombuffer(buf, dtype=chunk, count=height, offset=first)
    else:
        chunks = np.stack([np.frombuffer(buf, dtype=chunk, count=1, offset=int(o))[0] for o in offsets])
    order = np.argsort(chunks["y"])
    rows = chunks["row"][order]
    out = {}
    for name, ptype in channels:
        data = rows[name]
        out[name] = data.astype(np.float32) if ptype == 1 else np.ascontiguousarray(data)
    return out
