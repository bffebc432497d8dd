"""Minimal PNG writer and reader (8-bit RGB/RGBA, non-interlaced).

Only `zlib` and `struct` are used so that rendering previews never depends on
Pillow. The reader exists mainly for the tests and understands exactly the
subset the writer produces, plus the standard row filters so that files
re-saved by other tools still load.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import Union

import numpy as np

PathLike = Union[str, Path]

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# PNG colour types for 8-bit truecolour without / with alpha.
_COLOR_TYPE = {3: 2, 4: 6}
_CHANNELS = {2: 3, 6: 4}


def _chunk(tag: bytes, data: bytes) -> bytes:
    """One PNG chunk: length, tag, payload, CRC over tag + payload."""
    crc = zlib.crc32(tag + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", crc)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Quantize a float image in [0, 1] to uint8 (clamped, NaN -> 0)."""
    img = np.asarray(image)
    if img.dtype == np.uint8:
        return img
    img = np.nan_to_num(img.astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    # Round to nearest so that v/255 survives a write/read round trip.
    return np.rint(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)


def write_png(path: PathLike, image: np.ndarray) -> None:
    """Write an `(H, W, 3|4)` image (float in [0, 1], or uint8); row 0 = top."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in _COLOR_TYPE or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"write_png: expected an (H, W, 3|4) image, got shape {img.shape}")
    if not (np.issubdtype(img.dtype, np.floating) or img.dtype == np.uint8):
        raise TypeError(f"write_png: expected a float or uint8 image, got {img.dtype}")
    pixels = to_uint8(img)
    height, width, channels = pixels.shape
    # Every scanline starts with filter type 0 (None); zlib does the compression.
    rows = np.zeros((height, width * channels + 1), dtype=np.uint8)
    rows[:, 1:] = pixels.reshape(height, -1)
    header = struct.pack(">IIBBBBB", width, height, 8, _COLOR_TYPE[channels], 0, 0, 0)
    data = (_SIGNATURE + _chunk(b"IHDR", header)
            + _chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + _chunk(b"IEND", b""))
    Path(path).write_bytes(data)


def _read_chunks(data: bytes, name: str) -> dict[bytes, bytes]:
    """Split a PNG stream into chunks (IDAT concatenated), checking CRCs."""
    if not data.startswith(_SIGNATURE):
        raise ValueError(f"{name}: not a PNG file (bad signature)")
    chunks: dict[bytes, bytes] = {}
    pos = len(_SIGNATURE)
    while pos < len(data):
        if pos + 12 > len(data):
            raise ValueError(f"{name}: truncated chunk at byte {pos}")
        (length,) = struct.unpack_from(">I", data, pos)
        tag = data[pos + 4:pos + 8]
        payload = data[pos + 8:pos + 8 + length]
        if len(payload) != length or pos + 12 + length > len(data):
            raise ValueError(f"{name}: truncated {tag!r} chunk")
        (crc,) = struct.unpack_from(">I", data, pos + 8 + length)
        if crc != zlib.crc32(tag + payload) & 0xFFFFFFFF:
            raise ValueError(f"{name}: CRC mismatch in {tag!r} chunk")
        chunks[tag] = chunks.get(tag, b"") + payload
        pos += 12 + length
        if tag == b"IEND":
            break
    for tag in (b"IHDR", b"IDAT", b"IEND"):
        if tag not in chunks:
            raise ValueError(f"{name}: missing {tag.decode()} chunk")
    return chunks


def _paeth(a: int, b: int, c: int) -> int:
    """The Paeth predictor of the PNG specification."""
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    return b if pb <= pc else c


def _unfilter(raw: np.ndarray, height: int, stride: int, bpp: int, name: str) -> np.ndarray:
    """Undo the per-scanline filters; types 0-2 are vectorized, 3-4 loop per byte."""
    rows = raw.reshape(height, stride + 1)
    out = np.zeros((height, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.uint8)
    for y in range(height):
        kind, line = rows[y, 0], rows[y, 1:]
        if kind == 0:
            cur = line.copy()
        elif kind == 1:  # Sub: running sum per channel, modulo 256.
            cur = (np.cumsum(line.reshape(-1, bpp).astype(np.int64), axis=0) % 256)
            cur = cur.astype(np.uint8).reshape(-1)
        elif kind == 2:  # Up
            cur = line + prev
        elif kind in (3, 4):
            cur, up = line.astype(np.int64), prev.astype(np.int64)
            for i in range(stride):
                left = cur[i - bpp] if i >= bpp else 0
                upleft = up[i - bpp] if i >= bpp else 0
                pred = (left + up[i]) // 2 if kind == 3 else _paeth(left, up[i], upleft)
                cur[i] = (cur[i] + pred) & 0xFF
            cur = cur.astype(np.uint8)
        else:
            raise ValueError(f"{name}: unknown filter type {kind} in row {y}")
        out[y] = cur
        prev = cur
    return out


def read_png(path: PathLike) -> np.ndarray:
    """Read an 8-bit RGB/RGBA non-interlaced PNG as a uint8 `(H, W, 3|4)` array."""
    name = str(path)
    chunks = _read_chunks(Path(path).read_bytes(), name)
    if len(chunks[b"IHDR"]) != 13:
        raise ValueError(f"{name}: malformed IHDR chunk")
    width, height, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", chunks[b"IHDR"])
    if depth != 8 or color not in _CHANNELS or interlace != 0:
        raise ValueError(f"{name}: only 8-bit RGB/RGBA non-interlaced PNGs are supported "
                         f"(bit depth {depth}, colour type {color}, interlace {interlace})")
    channels = _CHANNELS[color]
    try:
        raw = np.frombuffer(zlib.decompress(chunks[b"IDAT"]), dtype=np.uint8)
    except zlib.error as exc:
        raise ValueError(f"{name}: corrupt image data ({exc})") from None
    stride = width * channels
    if raw.size != height * (stride + 1):
        raise ValueError(f"{name}: image data has {raw.size} bytes, "
                         f"expected {height * (stride + 1)}")
    return _unfilter(raw, height, stride, channels, name).reshape(height, width, channels)
