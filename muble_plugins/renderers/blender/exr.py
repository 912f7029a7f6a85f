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


def _read_header(buf: bytes, pos: int) -> tuple[dict[str, bytes], int]:
    attrs = {}
    while buf[pos] != 0:
        name, pos = _read_cstring(buf, pos)
        _type, pos = _read_cstring(buf, pos)
        (size,) = struct.unpack_from("<i", buf, pos)
        pos += 4
        attrs[name] = buf[pos:pos + size]
        pos += size
    return attrs, pos + 1


def _part_layout(path: Path, attrs: dict[str, bytes]) -> tuple[int, int, list[tuple[str, int]]]:
    if attrs["compression"][0] != 0:
        raise RenderError(f"{path} is compressed (codec {attrs['compression'][0]}); set exr_codec='NONE'")
    if b"tiled" in attrs.get("type", b""):
        raise RenderError(f"{path} is tiled; write render passes as scan lines")
    xmin, ymin, xmax, ymax = struct.unpack("<iiii", attrs["dataWindow"])
    return xmax - xmin + 1, ymax - ymin + 1, _channel_list(attrs["channels"])


def read_exr(path: str | Path) -> dict[str, np.ndarray]:
    """All channels of an uncompressed scan-line EXR (single or multi-part) as float32 or uint32 arrays of
    shape (height, width), top row first."""
    path = Path(path)
    buf = path.read_bytes()
    magic, version = struct.unpack_from("<ii", buf, 0)
    if magic != _MAGIC:
        raise RenderError(f"{path} is not an OpenEXR file")
    if version & 0x200:
        raise RenderError(f"{path} is tiled; write render passes as scan lines")
    multipart = bool(version & 0x1000)
    headers, pos = [], 8
    while True:
        attrs, pos = _read_header(buf, pos)
        headers.append(attrs)
        if not multipart or buf[pos] == 0:
            break
    if multipart:
        pos += 1  # the empty header that ends the list
    layouts = [_part_layout(path, attrs) for attrs in headers]
    tables = []
    for _width, height, _channels in layouts:
        tables.append(np.frombuffer(buf, dtype="<u8", count=height, offset=pos).astype(np.int64))
        pos += 8 * height
    out: dict[str, np.ndarray] = {}
    for (width, height, channels), offsets in zip(layouts, tables):
        # One scan line per chunk when uncompressed; each holds every channel's row, in channel-list order.
        row = np.dtype([(name, _PIXEL_TYPES[ptype], (width,)) for name, ptype in channels])
        prefix = [("part", "<i4")] if multipart else []
        chunk = np.dtype([*prefix, ("y", "<i4"), ("size", "<i4"), ("row", row)])
        if np.all(np.diff(offsets) == chunk.itemsize):
            # Chunks are contiguous: read them in one strided view (what Blender writes).
            chunks = np.frombuffer(buf, dtype=chunk, count=height, offset=int(offsets[0]))
        else:
            chunks = np.concatenate([np.frombuffer(buf, dtype=chunk, count=1, offset=int(o)) for o in offsets])
        rows = chunks["row"][np.argsort(chunks["y"], kind="stable")]
        for name, ptype in channels:
            data = rows[name]
            out[name] = data.astype(np.float32) if ptype == 1 else np.ascontiguousarray(data)
    return out
