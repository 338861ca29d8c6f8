"""The world a robot localizes in: point landmarks with ids and an occupancy grid.

Conventions (SI units, as everywhere)
-------------------------------------
* A landmark is a point ``(m_x, m_y)`` [m] with an integer id ≥ 0; ids are unique.
* An :class:`OccupancyGrid` holds square cells of side ``resolution`` [m]; cell
  ``[i, j]`` (x index first, as :class:`~pose_uncertainty.core.grids.Grid`)
  spans ``origin + (i, j)·h … origin + (i+1, j+1)·h``: ``origin`` is the
  lower-left *corner* of cell ``[0, 0]`` (the ROS ``map_server`` convention), so
  cell centres are ``origin + (i + ½, j + ½)·h``.
* ``occupied`` cells stop a laser beam; ``free`` cells are known to be free
  (robots start there in global localization). A cell may be neither (unknown,
  grey in an image): it does not stop beams and nobody is placed there.

Sources of the grid
-------------------
* wall segments ``(x1, y1, x2, y2)`` rasterised at ``resolution``: a cell is
  occupied when a segment comes within ``thickness/2 + h·√2/2`` of its centre
  (every cell a segment touches, so a thin diagonal wall has no gaps a beam could
  slip through); the grid covers the segments plus ``margin`` [m];
* an image (PGM read with numpy, P2 or P5; PNG through Pillow) with
  ``resolution``, ``origin``, ``occupied_thresh``, ``free_thresh`` and ``negate``
  as in ROS: a pixel of grey level ``v ∈ [0, 1]`` has occupancy ``p = 1 − v``
  (``p = v`` when negated); ``p > occupied_thresh`` is occupied and
  ``p < free_thresh`` free. The image's first row is the top of the map.

World files (YAML or JSON) are validated against :data:`WORLD_SCHEMA`; a bad file
raises one ``ValueError`` line naming the key, the value and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.grids import Grid
from ..core.input_files import read_mapping_file
from ..core.schema import first_error
from ..core.validation import check_finite, check_last_axis, check_positive, check_positive_int

__all__ = [
    "WORLD_SCHEMA",
    "OccupancyGrid",
    "World",
    "grid_from_image",
    "grid_from_segments",
    "load_world",
    "read_image",
    "rectangle_segments",
    "sample_free_poses",
    "world_from_dict",
]

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

_NUMBER = {"type": "number"}
#: JSON Schema (2020-12) of a world file; every key has a description.
WORLD_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "name": {"type": "string", "description": "name of the world"},
        "landmarks": {
            "description": "point landmarks with unique integer ids [m]",
            "type": "array",
            "items": {
                "type": "object",
                "additionalProperties": False,
                "required": ["id", "x", "y"],
                "properties": {
                    "id": {"type": "integer", "minimum": 0, "description": "landmark id"},
                    "x": {**_NUMBER, "description": "x [m]"},
                    "y": {**_NUMBER, "description": "y [m]"},
                },
            },
        },
        "bounds": {
            "description": "[x_min, x_max, y_min, y_max] [m] of a world without a grid",
            "type": "array",
            "items": _NUMBER,
            "minItems": 4,
            "maxItems": 4,
        },
        "walls": {
            "description": "occupancy grid rasterised from wall segments",
            "type": "object",
            "additionalProperties": False,
            "required": ["segments", "resolution"],
            "properties": {
                "segments": {
                    "description": "wall segments [x1, y1, x2, y2] [m]",
                    "type": "array",
                    "minItems": 1,
                    "items": {"type": "array", "items": _NUMBER, "minItems": 4, "maxItems": 4},
                },
                "resolution": {"type": "number", "exclusiveMinimum": 0, "maximum": 10,
                               "description": "cell side [m]"},
                "thickness": {"type": "number", "minimum": 0, "maximum": 10,
                              "description": "wall thickness [m] (default 0)"},
                "margin": {"type": "number", "minimum": 0, "maximum": 100,
                           "description": "grid margin around the segments [m] (default 1 cell)"},
            },
        },
        "image": {
            "description": "occupancy grid read from a PGM or PNG image",
            "type": "object",
            "additionalProperties": False,
            "required": ["path", "resolution", "origin"],
            "properties": {
                "path": {"type": "string", "description": "image path, relative to the world file"},
                "resolution": {"type": "number", "exclusiveMinimum": 0, "maximum": 10,
                               "description": "pixel side [m]"},
                "origin": {"type": "array", "items": _NUMBER, "minItems": 2, "maxItems": 2,
                           "description": "lower-left corner of the image [m]"},
                "occupied_thresh": {"type": "number", "exclusiveMinimum": 0, "maximum": 1,
                                    "description": "occupancy above which a pixel is occupied"},
                "free_thresh": {"type": "number", "minimum": 0, "exclusiveMaximum": 1,
                                "description": "occupancy below which a pixel is free"},
                "negate": {"type": "boolean", "description": "white = occupied"},
            },
        },
    },
}


# ============================================================================= grid


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """Occupancy of square cells.

    Attributes
    ----------
    occupied : ndarray of bool, shape (nx, ny) — cells that stop a beam
    free : ndarray of bool, shape (nx, ny) — cells known to be free
    resolution : float [m] — cell side ``h``
    origin : ndarray, shape (2,) [m] — lower-left corner of cell ``[0, 0]``
    """

    occupied: BoolArray
    free: BoolArray
    resolution: float
    origin: Array = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupied, dtype=bool)
        fr = np.asarray(self.free, dtype=bool)
        if occ.ndim != 2 or occ.shape != fr.shape or occ.size == 0:
            raise ValueError(
                "occupied and free must be non-empty 2-D arrays of one shape (allowed: (nx, ny)), "
                f"got shapes {occ.shape} and {fr.shape}"
            )
        if np.any(occ & fr):
            raise ValueError("free must not include occupied cells (allowed: disjoint masks)")
        origin = check_finite("origin", self.origin)
        if origin.shape != (2,):
            raise ValueError(f"origin must have shape (2,), got shape {origin.shape}")
        for arr in (occ, fr, origin):
            arr.setflags(write=False)
        object.__setattr__(self, "occupied", occ)
        object.__setattr__(self, "free", fr)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "resolution", float(check_positive("resolution", self.resolution)))

    @property
    def shape(self) -> tuple[int, int]:
        """``(nx, ny)``."""
        return int(self.occupied.shape[0]), int(self.occupied.shape[1])

    @property
    def x(self) -> Array:
        """Cell-centre x, shape (nx,) [m]."""
        return self.origin[0] + self.resolution * (np.arange(self.shape[0]) + 0.5)

    @property
    def y(self) -> Array:
        """Cell-centre y, shape (ny,) [m]."""
        return self.origin[1] + self.resolution * (np.arange(self.shape[1]) + 0.5)

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the cell walls [m]."""
        nx, ny = self.shape
        h = self.resolution
        x0, y0 = float(self.origin[0]), float(self.origin[1])
        return x0, x0 + nx * h, y0, y0 + ny * h

    def cell_of(self, xy: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64], BoolArray]:
        """Cell indices ``(i, j)`` of positions (shape (..., 2)) and whether they lie on the grid."""
        p = check_last_axis("xy", xy, 2)
        i = np.floor((p[..., 0] - self.origin[0]) / self.resolution).astype(np.int64)
        j = np.floor((p[..., 1] - self.origin[1]) / self.resolution).astype(np.int64)
        nx, ny = self.shape
        inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        return i, j, inside

    def is_occupied(self, xy: ArrayLike) -> BoolArray:
        """Whether positions (shape (..., 2)) lie in occupied cells (off the grid: False)."""
        i, j, inside = self.cell_of(xy)
        nx, ny = self.shape
        return inside & self.occupied[np.clip(i, 0, nx - 1), np.clip(j, 0, ny - 1)]

    def pose_grid(self, ntheta: int, theta0: float = -math.pi) -> Grid:
        """The ``(x, y, θ)`` grid of a histogram filter on these cells (``ntheta`` headings)."""
        h = self.resolution
        nx, ny = self.shape
        return Grid.square(float(self.origin[0]) + h / 2, float(self.origin[1]) + h / 2, nx, ny, h,
                       check_positive_int("ntheta", ntheta), theta0)  # fmt: skip


def rectangle_segments(x_min: float, x_max: float, y_min: float, y_max: float) -> Array:
    """The four walls of a rectangular room as segments, shape (4, 4) ``[x1, y1, x2, y2]`` [m]."""
    if not (x_max > x_min and y_max > y_min):
        raise ValueError(
            "room bounds must satisfy x_max > x_min and y_max > y_min (allowed: a non-empty "
            f"rectangle), got ({x_min}, {x_max}, {y_min}, {y_max})"
        )
    return np.array(
        [[x_min, y_min, x_max, y_min], [x_max, y_min, x_max, y_max],
         [x_max, y_max, x_min, y_max], [x_min, y_max, x_min, y_min]], dtype=np.float64,
    )  # fmt: skip


def _segment_distance(px: Array, py: Array, seg: Array) -> Array:
    """Distance from points to one segment ``[x1, y1, x2, y2]``; a zero-length segment is a point."""
    ax, ay, bx, by = seg
    dx, dy = bx - ax, by - ay
    len2 = dx * dx + dy * dy
    t = np.zeros_like(px) if len2 == 0 else np.clip(((px - ax) * dx + (py - ay) * dy) / len2, 0, 1)
    return np.hypot(px - (ax + t * dx), py - (ay + t * dy))


def grid_from_segments(
    segments: ArrayLike, resolution: float, thickness: float = 0.0, margin: float | None = None
) -> OccupancyGrid:
    """Rasterise wall segments (shape (S, 4) ``[x1, y1, x2, y2]`` [m]) into an occupancy grid.

    A cell is occupied when a segment passes within ``thickness/2 + h√2/2`` of its
    centre; every other cell is free. The grid covers the segments' bounding box
    plus ``margin`` [m] (default one cell) on every side.
    """
    seg = check_finite("segments", segments)
    if seg.ndim != 2 or seg.shape[1] != 4 or seg.shape[0] == 0:
        raise ValueError(f"segments must have shape (S, 4) with S >= 1, got shape {seg.shape}")
    h = float(check_positive("resolution", resolution))
    half = float(check_finite("thickness", thickness)) / 2
    if half < 0:
        raise ValueError(f"thickness must be >= 0 (allowed: [0, inf)), got {2 * half}")
    pad = h if margin is None else float(check_finite("margin", margin))
    lo = np.array([seg[:, [0, 2]].min(), seg[:, [1, 3]].min()]) - pad - half
    hi = np.array([seg[:, [0, 2]].max(), seg[:, [1, 3]].max()]) + pad + half
    n = np.maximum(np.ceil((hi - lo) / h - 1e-9).astype(int), 1)
    xc = lo[0] + h * (np.arange(n[0]) + 0.5)
    yc = lo[1] + h * (np.arange(n[1]) + 0.5)
    X, Y = np.meshgrid(xc, yc, indexing="ij")
    occ = np.zeros(X.shape, dtype=bool)
    reach = half + h * math.sqrt(2.0) / 2.0
    for s in seg:
        occ |= _segment_distance(X, Y, s) <= reach
    return OccupancyGrid(occ, ~occ, h, lo)


def _read_pgm(path: Path) -> Array:
    """Grey levels in [0, 1] of a PGM image (P2 ASCII or P5 binary), shape (rows, cols)."""
    data = path.read_bytes()
    tokens: list[bytes] = []
    pos = 0
    while len(tokens) < 4:  # magic, width, height, maxval; comments start with '#'
        while pos < len(data) and data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while end < len(data) and not data[end : end + 1].isspace():
            end += 1
        tokens.append(data[pos:end])
        pos = end
    magic, w, h, maxval = tokens[0], int(tokens[1]), int(tokens[2]), int(tokens[3])
    if magic == b"P5":
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        pix = np.frombuffer(data, dtype=dtype, count=w * h, offset=pos + 1)
    elif magic == b"P2":
        pix = np.array(data[pos:].split()[: w * h], dtype=np.int64)
    else:
        raise ValueError(f"image {path.name} must be a PGM of type P2 or P5, got magic {magic!r}")
    if pix.size != w * h:
        raise ValueError(f"image {path.name} must hold {w}x{h} pixels, got {pix.size}")
    return pix.reshape(h, w).astype(np.float64) / maxval


def read_image(path: str | Path) -> Array:
    """Grey levels in [0, 1] of a PGM or PNG image, shape (rows, cols), first row = top."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".pgm":
        return _read_pgm(p)
    if suffix == ".png":
        from PIL import Image  # imported where used: only image maps need it

        with Image.open(p) as im:
            if im.mode.startswith("I"):  # 16-bit grey
                return np.asarray(im, dtype=np.float64) / 65535.0
            rgb = np.asarray(im if im.mode == "L" else im.convert("RGB"), dtype=np.float64) / 255.0
        return rgb if rgb.ndim == 2 else rgb.mean(axis=-1)
    raise ValueError(f"image path must end in .pgm or .png (allowed: PGM, PNG), got {p.name!r}")


def grid_from_image(
    grey: ArrayLike,
    resolution: float,
    origin: ArrayLike = (0.0, 0.0),
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    negate: bool = False,
) -> OccupancyGrid:
    """Occupancy grid from grey levels (shape (rows, cols), row 0 = top), ROS map_server rules."""
    v = check_finite("image", grey)
    if v.ndim != 2:
        raise ValueError(f"image must be 2-D grey levels, got shape {v.shape}")
    p = v if negate else 1.0 - v
    cells = p[::-1, :].T  # row 0 is the top: flip, then x index first
    return OccupancyGrid(cells > occupied_thresh, cells < free_thresh, resolution,
                         check_finite("origin", origin))  # fmt: skip


# ============================================================================= world


@dataclass(frozen=True, eq=False)
class World:
    """Landmarks, an optional occupancy grid and the wall segments it came from.

    Attributes
    ----------
    landmarks : ndarray, shape (L, 2) [m]
    landmark_ids : ndarray of int, shape (L,) — unique
    grid : OccupancyGrid or None
    segments : ndarray, shape (S, 4) [m] — wall segments (empty when the grid is an image)
    bounds : tuple (x_min, x_max, y_min, y_max) [m] — the region robots live in
    name : str
    """

    landmarks: Array
    landmark_ids: NDArray[np.int64]
    grid: OccupancyGrid | None = None
    segments: Array = field(default_factory=lambda: np.zeros((0, 4)))
    bounds: tuple[float, float, float, float] | None = None
    name: str = ""

    def __post_init__(self) -> None:
        lm = check_finite("landmarks", np.asarray(self.landmarks, dtype=np.float64).reshape(-1, 2))
        ids = np.asarray(self.landmark_ids)
        if ids.shape != (lm.shape[0],) or (ids.size and not np.issubdtype(ids.dtype, np.integer)):
            raise ValueError(
                f"landmark_ids must be {lm.shape[0]} integers (one per landmark), got {ids.tolist()}"
            )
        uniq, counts = np.unique(ids, return_counts=True)
        if np.any(counts > 1):
            raise ValueError(
                f"landmarks.id must be unique (allowed: distinct integers), got {uniq[counts > 1].tolist()} twice"
            )
        seg = np.asarray(self.segments, dtype=np.float64).reshape(-1, 4)
        b = self.bounds
        if b is None:
            b = self.grid.extent() if self.grid is not None else _landmark_bounds(lm)
        bb = [float(v) for v in check_finite("bounds", b)]
        if len(bb) != 4 or not (bb[1] > bb[0] and bb[3] > bb[2]):
            raise ValueError(
                f"bounds must be [x_min, x_max, y_min, y_max] with x_max > x_min and y_max > y_min, got {bb}"
            )
        b = (bb[0], bb[1], bb[2], bb[3])
        object.__setattr__(self, "landmarks", lm)
        object.__setattr__(self, "landmark_ids", ids.astype(np.int64))
        object.__setattr__(self, "segments", seg)
        object.__setattr__(self, "bounds", b)

    @property
    def n_landmarks(self) -> int:
        """Number of landmarks ``L``."""
        return int(self.landmarks.shape[0])


def _landmark_bounds(lm: Array) -> tuple[float, float, float, float]:
    if lm.shape[0] == 0:
        raise ValueError("a world must have landmarks, walls, an image or bounds (allowed: at least one)")
    lo, hi = lm.min(axis=0) - 1.0, lm.max(axis=0) + 1.0
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def sample_free_poses(world: World, n: int, rng: np.random.Generator) -> Array:
    """Poses drawn uniformly over the free space, headings uniform on [−π, π).

    With a grid: a free cell uniformly, then a uniform position inside it (so the
    density is uniform over the union of free cells). Without: uniform over ``bounds``.

    Returns
    -------
    ndarray, shape (n, 3) [m, m, rad]
    """
    n = check_positive_int("n", n)
    g = world.grid
    theta = rng.uniform(-math.pi, math.pi, n)
    if g is None:
        x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
        return np.stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), theta], axis=-1)
    free = np.flatnonzero(g.free.ravel())
    if free.size == 0:
        raise ValueError("world grid must have free cells to sample from (allowed: >= 1), got 0")
    cell = free[rng.integers(0, free.size, n)]
    i, j = np.divmod(cell, g.shape[1])
    u = rng.random((n, 2))
    x = g.origin[0] + (i + u[:, 0]) * g.resolution
    y = g.origin[1] + (j + u[:, 1]) * g.resolution
    return np.stack([x, y, theta], axis=-1)


# ============================================================================= files


def _validate(data: Any) -> None:
    if not isinstance(data, Mapping):
        raise ValueError(  # noqa: TRY004 - a bad world file is a ValueError like every bad input
            f"world file must hold a mapping (allowed: YAML/JSON object), got {type(data).__name__}"
        )
    problem = first_error(WORLD_SCHEMA, data, what="world")
    if problem is not None:
        raise ValueError(problem)
    if "walls" in data and "image" in data:
        raise ValueError("world keys 'walls' and 'image' are exclusive (allowed: one grid source), got both")
    b = data.get("bounds")
    if b is not None and not (b[1] > b[0] and b[3] > b[2]):
        raise ValueError(f"world key 'bounds' has bad value {b}; allowed: x_max > x_min and y_max > y_min")
    img = data.get("image", {})
    if img.get("free_thresh", 0.196) >= img.get("occupied_thresh", 0.65):
        raise ValueError(
            f"world key 'image.free_thresh' has bad value {img.get('free_thresh', 0.196)}; "
            f"allowed: < occupied_thresh = {img.get('occupied_thresh', 0.65)}"
        )


def world_from_dict(data: Mapping[str, Any], base_dir: str | Path = ".") -> World:
    """Build a :class:`World` from a mapping shaped like :data:`WORLD_SCHEMA` (validated first).

    ``base_dir`` resolves a relative ``image.path``.
    """
    _validate(data)
    lms: Sequence[Mapping[str, Any]] = data.get("landmarks", [])
    ids = np.array([int(m["id"]) for m in lms], dtype=np.int64)
    uniq, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        raise ValueError(f"world key 'landmarks.id' has bad value {int(uniq[counts > 1][0])} (repeated); allowed: unique ids")
    xy = np.array([[m["x"], m["y"]] for m in lms], dtype=np.float64).reshape(-1, 2)
    grid, seg = None, np.zeros((0, 4))
    if "walls" in data:
        w = data["walls"]
        seg = np.asarray(w["segments"], dtype=np.float64)
        grid = grid_from_segments(seg, w["resolution"], w.get("thickness", 0.0), w.get("margin"))
    elif "image" in data:
        im = data["image"]
        grey = read_image(Path(base_dir) / im["path"])
        grid = grid_from_image(grey, im["resolution"], im["origin"], im.get("occupied_thresh", 0.65),
                               im.get("free_thresh", 0.196), bool(im.get("negate", False)))  # fmt: skip
    b = data.get("bounds")
    bounds = None if b is None else (float(b[0]), float(b[1]), float(b[2]), float(b[3]))
    return World(xy, ids, grid, seg, bounds, str(data.get("name", "")))


def load_world(path: str | Path) -> World:
    """Read a world file (``.yaml``, ``.yml`` or ``.json``), validate it and build the :class:`World`."""
    p = Path(path)
    data = read_mapping_file(p, "world")  # kind and size checked first, a repeated key refused
    return world_from_dict(data, p.parent)
