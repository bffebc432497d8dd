"""A perspective camera that frames the image exactly as Blender does.

Blender's convention (`BKE_camera_params_compute_viewplane`, `BKE_camera_sensor_fit`,
`BKE_camera_sensor_size` in blenkernel/intern/camera.cc; Cycles' `blender_camera_viewplane`
agrees):

* The camera looks down its local -Z axis, +Y is image up, +X is image right.
* Sensor fit picks which image axis the sensor spans. AUTO compares
  `width * pixel_aspect_x` with `height * pixel_aspect_y` and fits the larger one,
  but always uses `sensor_width`; HORIZONTAL fits the width with `sensor_width`;
  VERTICAL fits the height with `sensor_height`.
* With `ycor = pixel_aspect_y / pixel_aspect_x`, the image plane at unit distance
  spans `x in [-W/2, W/2] * s` and `y in [-ycor*H/2, ycor*H/2] * s`, where
  `s = sensor / (lens * viewfac)` and `viewfac` is `W` (horizontal fit) or `ycor*H`
  (vertical fit). So the fitted axis spans exactly `sensor / lens`.
* Shifts move that window by `shift * viewfac` pixels, i.e. in units of the
  fitted dimension (the larger one under AUTO).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Sequence

import numpy as np

SENSOR_FITS = ("AUTO", "HORIZONTAL", "VERTICAL")

# Accepted ranges (low, high, unit). Blender's fields offer lens >= 1 mm (up to
# 5000 on the slider), sensors >= 1 mm (up to 100), shifts of -2..2 on the
# slider (-10..10 in older versions) and pixel aspects 1..200 each (so a
# ratio in 0.005..200): every real Blender camera fits with a wide margin,
# and the extremes keep every ray direction finite and non-zero.
RANGES = {
    "lens": (1e-3, 1e6, " mm"),
    "sensor_width": (1e-3, 1e6, " mm"),
    "sensor_height": (1e-3, 1e6, " mm"),
    "shift_x": (-100.0, 100.0, ""),
    "shift_y": (-100.0, 100.0, ""),
    "clip_start": (1e-9, 1e30, ""),
    "pixel_aspect": (1e-3, 1e3, ""),
}
FOV_RANGE = (0.01, 179.9)  # look_at's fov_deg, degrees
MAX_COORDINATE = 1e30       # camera position, so that float32 origins stay finite
RAY_ORDERS = ("image", "tiles")
# Pixels on a side of tile_order's tiles: a 16-ray packet is one tile, an
# 8-ray one half of it. Square packets share more nodes than rows do: 4 x 4
# traced about 3% faster than 8 x 2, and 8 x 2 12% faster than 16 x 1
# (kd, primary rays on bunny and dragon, 2026-11-30).
TILE = 4


def tile_order(width: int, height: int, tile: int = TILE) -> np.ndarray:
    """The pixels (row-major indices) tile by tile: tiles of `tile` x `tile`
    pixels in row-major order over the image, the pixels row-major inside a
    tile (the right and bottom tiles are cut at the image's edge). So with
    the default 4 x 4 tiles, 4, 8 or 16 consecutive pixels - one ray packet -
    are one, two or four rows of a tile.
    `image[tile_order(w, h)]` puts an image's pixels in this order, and
    `out[tile_order(w, h)] = traced` puts them back."""
    _check_size(width, height)
    if not _is_int(tile) or tile <= 0:
        raise ValueError(f"tile_order: tile must be a positive integer, got {tile!r}")
    # The pixel indices padded with -1 to whole tiles, then tile rows,
    # tiles, and rows inside tiles as axes: one pass, no sort.
    tiles_y, tiles_x = -(-height // tile), -(-width // tile)
    grid = np.full((tiles_y * tile, tiles_x * tile), -1, dtype=np.int64)
    grid[:height, :width] = np.arange(width * height, dtype=np.int64).reshape(height, width)
    order = grid.reshape(tiles_y, tile, tiles_x, tile).transpose(0, 2, 1, 3).ravel()
    return order[order >= 0]


def image_order(values: dict, order: np.ndarray) -> dict:
    """Per-ray arrays traced in `order` (e.g. `tile_order(w, h)`), each put
    back in image order."""
    out = {}
    for key, traced in values.items():
        out[key] = np.empty_like(traced)
        out[key][order] = traced
    return out


def _is_number(value: Any) -> bool:
    """True for Python/numpy reals, but not for bools."""
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, (bool, np.bool_)))


def _is_int(value: Any) -> bool:
    """True for Python/numpy integers, but not for bools or integral floats."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


@dataclass
class Camera:
    """Blender-style perspective camera. Lengths in mm, shifts in frame units."""

    matrix_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    lens: float = 50.0
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: str = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    pixel_aspect: float = 1.0  # pixel_aspect_x / pixel_aspect_y

    def __post_init__(self) -> None:
        self.matrix_world = _matrix(self.matrix_world, copy=True)  # not the caller's array
        self.validate()

    # -- validation -----------------------------------------------------------

    def validate(self) -> None:
        """TypeError for a value that is not a number, ValueError for one
        outside the ranges in RANGES (which hold every camera Blender's own
        fields offer, with a wide margin)."""
        self.matrix_world = _matrix(self.matrix_world, copy=False)
        for name, (low, high, unit) in RANGES.items():
            value = getattr(self, name)
            if not _is_number(value):
                raise TypeError(f"Camera: {name} must be a number, got {type(value).__name__} "
                                f"{value!r}")
            if not (math.isfinite(value) and low <= value <= high):
                raise ValueError(f"Camera: {name} must be in {_g(low)}..{_g(high)}{unit}, "
                                 f"got {value!r}")
        if not _is_number(self.clip_end):
            raise TypeError(f"Camera: clip_end must be a number, got "
                            f"{type(self.clip_end).__name__} {self.clip_end!r}")
        if not math.isfinite(self.clip_end) or self.clip_end <= self.clip_start:
            raise ValueError(f"Camera: clip_end ({self.clip_end}) must be finite and exceed "
                             f"clip_start ({self.clip_start})")
        if self.sensor_fit not in SENSOR_FITS:
            raise ValueError(f"Camera: sensor_fit must be one of {SENSOR_FITS}, "
                             f"got {self.sensor_fit!r}")

    # -- construction ---------------------------------------------------------

    @classmethod
    def look_at(cls, eye: Sequence[float], target: Sequence[float],
                up: Sequence[float] = (0.0, 0.0, 1.0), fov_deg: float = 50.0,
                sensor_width: float = 36.0, **kwargs: Any) -> "Camera":
        """A camera at `eye` looking at `target`.

        `fov_deg` is the angle spanned by `sensor_width` (Blender's `angle_x`):
        the horizontal field of view for landscape images under AUTO fit.
        Extra keyword arguments are passed on to the constructor.
        """
        eye_v, target_v, up_v = (_point(v, n) for v, n in ((eye, "eye"), (target, "target"),
                                                           (up, "up")))
        if not _is_number(fov_deg):
            raise TypeError(f"Camera.look_at: fov_deg must be a number, got "
                            f"{type(fov_deg).__name__} {fov_deg!r}")
        if not FOV_RANGE[0] <= fov_deg <= FOV_RANGE[1]:  # also refuses NaN
            raise ValueError(f"Camera.look_at: fov_deg must be in {FOV_RANGE[0]:g}.."
                             f"{FOV_RANGE[1]:g} degrees, got {fov_deg!r}")
        if not _is_number(sensor_width):
            raise TypeError(f"Camera.look_at: sensor_width must be a number, got "
                            f"{type(sensor_width).__name__} {sensor_width!r}")
        forward = target_v - eye_v
        if not np.all(np.isfinite(forward)) or np.linalg.norm(forward) == 0.0:
            raise ValueError("Camera.look_at: eye and target must be distinct finite points")
        if not np.any(up_v):
            raise ValueError("Camera.look_at: up must not be the zero vector")
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, up_v)
        if np.linalg.norm(right) < 1e-9 * max(np.linalg.norm(up_v), 1e-300):
            # Looking along `up`: any perpendicular will do, pick a stable one.
            right = np.cross(forward, np.eye(3)[np.argmin(np.abs(forward))])
        right /= np.linalg.norm(right)
        cam_up = np.cross(right, forward)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, cam_up, -forward, eye_v
        lens = sensor_width / (2.0 * math.tan(math.radians(fov_deg) / 2.0))
        return cls(matrix_world=m, lens=lens, sensor_width=sensor_width, **kwargs)

    # -- framing --------------------------------------------------------------

    def fit(self, width: int, height: int) -> str:
        """The sensor fit ('HORIZONTAL' or 'VERTICAL') actually used for an image."""
        if self.sensor_fit != "AUTO":
            return self.sensor_fit
        # Blender compares aspect-corrected sizes; ties give the same frame either way.
        return "HORIZONTAL" if width * self.pixel_aspect >= height else "VERTICAL"

    def viewplane(self, width: int, height: int) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the image window on the camera's z = -1 plane."""
        _check_size(width, height)
        self.validate()
        ycor = 1.0 / self.pixel_aspect
        if self.fit(width, height) == "HORIZONTAL":
            sensor, viewfac = self.sensor_width, float(width)
        else:
            sensor = self.sensor_height if self.sensor_fit == "VERTICAL" else self.sensor_width
            viewfac = ycor * height
        scale = sensor / (self.lens * viewfac)  # unit-distance size of one viewfac unit
        dx, dy = self.shift_x * viewfac, self.shift_y * viewfac
        return ((-0.5 * width + dx) * scale, (0.5 * width + dx) * scale,
                (-0.5 * ycor * height + dy) * scale, (0.5 * ycor * height + dy) * scale)

    def rays(self, width: int, height: int, order: str = "image") -> tuple[np.ndarray, np.ndarray]:
        """Primary rays through pixel centres, row-major with row 0 = image top;
        with order="tiles", in `tile_order(width, height)` instead (coherent
        runs of consecutive rays, for `Tree.intersect(..., packets=True)`).

        Returns `(origins, directions)`, both float32 `(H*W, 3)`; directions are
        unit length. Rays start at the eye; `clip_start`/`clip_end` are only
        carried along for the caller (they are view-axis depths in Blender).
        """
        if order not in RAY_ORDERS:
            raise ValueError(f"Camera.rays: order must be one of {RAY_ORDERS}, got {order!r}")
        xmin, xmax, ymin, ymax = self.viewplane(width, height)
        xs = xmin + (np.arange(width) + 0.5) * ((xmax - xmin) / width)
        ys = ymax - (np.arange(height) + 0.5) * ((ymax - ymin) / height)  # top row first
        local = np.empty((height, width, 3))
        local[..., 0] = xs[None, :]
        local[..., 1] = ys[:, None]
        local[..., 2] = -1.0
        # Blender ignores object scale for the view, so use the unit axes.
        axes = self.matrix_world[:3, :3] / np.linalg.norm(self.matrix_world[:3, :3], axis=0)
        dirs = local.reshape(-1, 3) @ axes.T
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        if order == "tiles":
            dirs = dirs[tile_order(width, height)]
        # A real (H*W, 3) array, not a broadcast view: every trace would copy
        # a view into the contiguous rows the core reads.
        origins = np.repeat(self.matrix_world[None, :3, 3].astype(np.float32), len(dirs), axis=0)
        return origins, dirs.astype(np.float32)

    # -- serialization --------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-compatible dict (matrix as nested lists, row-major)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["matrix_world"] = self.matrix_world.tolist()
        return {k: (float(v) if isinstance(v, (np.floating, np.integer)) else v)
                for k, v in out.items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Camera":
        """Inverse of `to_dict`; unknown keys are an error, missing ones default."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"Camera.from_dict: unknown keys {sorted(unknown)}")
        return cls(**data)


def _g(x: float) -> str:
    """1e6 and 1e-9 rather than 1e+06 and 1e-09 in messages."""
    return f"{x:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def _matrix(value: Any, copy: bool) -> np.ndarray:
    """A float64 4x4 camera-to-world matrix with finite, non-zero axes."""
    try:
        m = (np.array if copy else np.asarray)(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"Camera: matrix_world must be a 4x4 array of numbers, got "
                        f"{type(value).__name__}") from None
    if m.shape != (4, 4):
        raise ValueError(f"Camera: matrix_world must be 4x4, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError("Camera: matrix_world contains NaN or inf")
    with np.errstate(over="ignore", under="ignore"):
        norms = np.linalg.norm(m[:3, :3], axis=0)
    if np.any(norms == 0.0) or not np.all(np.isfinite(norms)):
        raise ValueError("Camera: matrix_world has a zero-length (or overflowing) axis")
    if np.abs(m[:3, 3]).max() > MAX_COORDINATE:
        raise ValueError(f"Camera: the position {tuple(m[:3, 3])} is beyond "
                         f"+-{_g(MAX_COORDINATE)}")
    return m


def _point(value: Any, name: str) -> np.ndarray:
    """Three finite numbers as a float64 vector (look_at's eye, target, up)."""
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"Camera.look_at: {name} must be 3 numbers, got {value!r}") from None
    if v.shape != (3,):
        raise ValueError(f"Camera.look_at: {name} must be 3 numbers, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"Camera.look_at: {name} must be finite, got {tuple(v)}")
    return v


def _check_size(width: Any, height: Any) -> None:
    """Image sizes must be positive integers (not floats, not bools)."""
    for name, value in (("width", width), ("height", height)):
        if not _is_int(value) or value <= 0:
            raise ValueError(f"Camera: image {name} must be a positive integer, got {value!r}")
