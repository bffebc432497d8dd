"""Saving rendered images: 8-bit RGB/RGBA PNG through Pillow.

The core renders float images in [0, 1] with row 0 at the top; `write_png`
quantizes them and hands the bytes to Pillow, which does the encoding (and
every PNG variant on reading). Pillow is imported inside the functions so that
`import bsplab` works where it is absent (inside Blender the add-on shows its
images through bpy and never calls these).
"""

from __future__ import annotations

from pathlib import Path
from typing import Union

import numpy as np

PathLike = Union[str, Path]

# Pillow's names of the two layouts we write.
_MODES = {3: "RGB", 4: "RGBA"}


def _pillow():
    try:
        from PIL import Image
    except ImportError as exc:
        raise ImportError("writing and reading PNG images needs Pillow: "
                          "pip install 'bsplab[image]' (or pillow)") from exc
    return Image


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Quantize a float image in [0, 1] to uint8 (clamped, NaN -> 0, +inf -> 255)."""
    img = np.asarray(image)
    if img.dtype == np.uint8:
        return img
    img = np.nan_to_num(img.astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    # Round to nearest so that v/255 survives a write/read round trip.
    return np.rint(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)


def write_png(path: PathLike, image: np.ndarray) -> None:
    """Write an `(H, W, 3|4)` image (float in [0, 1], or uint8); row 0 = top."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in _MODES or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"write_png: expected an (H, W, 3|4) image, got shape {img.shape}")
    if not (np.issubdtype(img.dtype, np.floating) or img.dtype == np.uint8):
        raise TypeError(f"write_png: expected a float or uint8 image, got {img.dtype}")
    pixels = np.ascontiguousarray(to_uint8(img))
    _pillow().fromarray(pixels, _MODES[pixels.shape[2]]).save(Path(path), format="PNG")


def read_png(path: PathLike) -> np.ndarray:
    """A PNG as a uint8 `(H, W, 3|4)` array: RGBA when the file has transparency,
    else RGB (grey and palette images are expanded)."""
    Image = _pillow()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        with Image.open(path, formats=["PNG"]) as im:
            im.load()
            has_alpha = im.mode in ("RGBA", "LA", "PA") or "transparency" in im.info
            return np.asarray(im.convert("RGBA" if has_alpha else "RGB"))
    except (OSError, SyntaxError, ValueError) as exc:
        # Pillow reports a bad signature, CRC or truncated data with these.
        raise ValueError(f"{path}: not a readable PNG image ({exc})") from None
