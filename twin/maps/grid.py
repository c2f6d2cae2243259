"""Grid frames and occupancy grids.

A grid frame is the building's XY plane (IFC world coordinates, metres) cut into square cells of
``resolution_m``. Cell ``(row, col)`` covers ``x in [origin_x + col*res, origin_x + (col+1)*res]``
and ``y in [origin_y + row*res, origin_y + (row+1)*res]``. Row 0 is at the origin (the bottom, lowest
y): the same row-major layout as ``nav_msgs/OccupancyGrid``, so image writers flip rows.

Values follow ``nav_msgs/OccupancyGrid``: 0 free, 100 occupied, -1 unknown.

Grid planes are decided in the model's coordinates, not in float cell coordinates: the planes are
``origin + i * resolution`` (both read as the decimals they print as: 8.8 and 0.1, not their binary
neighbours), and a coordinate within ``TOLERANCES.grid_m`` (1 um) of a plane is on it
(:func:`grid_coordinates`); the half-open rule of the maps then decides. So ``(22.2 - 8.8) / 0.1``,
133.99999999999997 in float64, is line 134, and a building moved by whole cells (by (-1.1, 0.3) m or
by 10 km) keeps every cell. Frames are snapped the same way (:meth:`GridFrame.around`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from twin.errors import MapError
from twin.tolerances import TOLERANCES

FREE = np.int8(0)
OCCUPIED = np.int8(100)
UNKNOWN = np.int8(-1)

GridData = npt.NDArray[np.int8]

MAX_FRAME_CELLS = 400_000_000
"""The largest grid a frame may have (20,000 x 20,000 cells: a square kilometre at 5 cm, 400 MB).
An extent that needs more comes from an element far from the rest of its building."""


def grid_coordinates(
    values: npt.ArrayLike, origin: float, resolution_m: float, *, ends: tuple[float, ...] = ()
) -> npt.NDArray[np.float64]:
    """World coordinates ``values`` (metres) in grid units, ``(v - origin) / resolution_m``, where a value
    within ``TOLERANCES.grid_m`` of a plane ``origin + i * resolution_m`` is exactly ``i``, and one within
    it of an extra plane ``origin + e`` (``e`` in ``ends``, metres: a height band's ends) exactly
    :func:`grid_units` ``(e)``. Any shape.

    Example::

        grid_coordinates([22.2, 22.25], 8.8, 0.1)   # [134.0, 134.5] (float64 says 133.99999999999997)
    """
    v = np.asarray(values, dtype=np.float64)
    c = (v - origin) / resolution_m
    n = np.rint(c)
    tol = TOLERANCES.grid_m
    out: npt.NDArray[np.float64] = np.where(np.abs(v - (origin + n * resolution_m)) <= tol, n, c)
    for e in ends:
        if math.isfinite(e):
            out = np.where(np.abs(v - (origin + e)) <= tol, grid_units(e, resolution_m), out)
    return out


def grid_coordinate(value: float, origin: float, resolution_m: float) -> float:
    """:func:`grid_coordinates` of one value, in Python floats (no numpy call: for the few corners of a
    box, where numpy's fixed cost per call is most of the time); the same float, bit for bit."""
    c = (value - origin) / resolution_m
    n = float(round(c))  # half to even, as np.rint
    return n if abs(value - (origin + n * resolution_m)) <= TOLERANCES.grid_m else c


def grid_units(length_m: float, resolution_m: float) -> float:
    """A length in grid units: a whole number of cells when it is one within ``TOLERANCES.grid_m``
    (3.3000000000000007 m at 0.1 m is 33 cells, not 33.00000000000001)."""
    return float(grid_coordinates(length_m, 0.0, resolution_m))


def _plane(value: float, resolution_m: float, *, up: bool) -> int:
    """The grid plane ``i * resolution_m`` at or below (``up``: at or above) ``value``, a value within
    ``TOLERANCES.grid_m`` of a plane being on it."""
    c = value / resolution_m
    n = round(c)
    if abs(value - n * resolution_m) <= TOLERANCES.grid_m:
        return n
    return math.ceil(c) if up else math.floor(c)


@dataclass(frozen=True, slots=True)
class Window:
    """A rectangle of cells: rows ``[row0, row1)`` and columns ``[col0, col1)``."""

    row0: int
    col0: int
    row1: int
    col1: int

    @property
    def shape(self) -> tuple[int, int]:
        return (self.row1 - self.row0, self.col1 - self.col0)

    @property
    def empty(self) -> bool:
        return self.row1 <= self.row0 or self.col1 <= self.col0

    def meets(self, other: Window) -> bool:
        """The two windows share a cell (their intersection is not empty)."""
        rows = self.row0 < other.row1 and other.row0 < self.row1
        return rows and self.col0 < other.col1 and other.col0 < self.col1

    def intersect(self, other: Window) -> Window:
        return Window(
            max(self.row0, other.row0),
            max(self.col0, other.col0),
            min(self.row1, other.row1),
            min(self.col1, other.col1),
        )


@dataclass(frozen=True, slots=True)
class GridFrame:
    """Where a grid lies in the world: lower-left corner, cell size and size in cells."""

    origin_x: float
    origin_y: float
    resolution_m: float
    width: int
    height: int

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            msg = f"Grid resolution must be a positive number of metres, got {self.resolution_m!r}."
            raise MapError(msg)
        if not (math.isfinite(self.origin_x) and math.isfinite(self.origin_y)):
            msg = f"Grid origin must be finite, got ({self.origin_x!r}, {self.origin_y!r})."
            raise MapError(msg)
        if self.width <= 0 or self.height <= 0:
            msg = f"Grid size must be positive, got {self.width}x{self.height} cells."
            raise MapError(msg)

    @classmethod
    def around(
        cls,
        xmin: float,
        ymin: float,
        xmax: float,
        ymax: float,
        *,
        resolution_m: float,
        margin_m: float = 1.0,
    ) -> GridFrame:
        """The frame covering ``[xmin, xmax] x [ymin, ymax]`` plus ``margin_m``, origin snapped to cells:
        on the planes ``i * resolution_m``, a bound within ``TOLERANCES.grid_m`` of one being on it (so a
        building moved by whole cells has its frame moved by as many cells, whatever float says).

        Example::

            frame = GridFrame.around(0.0, 0.0, 10.0, 4.0, resolution_m=0.05, margin_m=1.0)
            assert (frame.origin_x, frame.width) == (-1.0, 240)
        """
        values = (xmin, ymin, xmax, ymax)
        if not all(math.isfinite(v) for v in values) or xmax < xmin or ymax < ymin:
            msg = f"Grid extent must be finite and ordered, got {values!r}."
            raise MapError(msg)
        res = resolution_m
        cells_x, cells_y = (xmax - xmin + 2 * margin_m) / res, (ymax - ymin + 2 * margin_m) / res
        if not cells_x * cells_y <= MAX_FRAME_CELLS:  # overflow to inf too
            msg = (
                f"Grid extent {values!r} at {res} m per cell needs about {cells_x:.3g} x {cells_y:.3g} "
                f"cells, more than the limit of {MAX_FRAME_CELLS:,}."
            )
            raise MapError(msg)
        col0, row0 = _plane(xmin - margin_m, res, up=False), _plane(ymin - margin_m, res, up=False)
        width = _plane(xmax + margin_m, res, up=True) - col0
        height = _plane(ymax + margin_m, res, up=True) - row0
        return cls(round(col0 * res, 9), round(row0 * res, 9), res, max(width, 1), max(height, 1))

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``: numpy shape of the grid's data."""
        return (self.height, self.width)

    @property
    def full(self) -> Window:
        return Window(0, 0, self.height, self.width)

    def window_for(self, xmin: float, ymin: float, xmax: float, ymax: float) -> Window:
        """The smallest window of cells covering the world rectangle, clipped to the grid."""
        res = self.resolution_m
        col0 = math.floor((xmin - self.origin_x) / res)
        row0 = math.floor((ymin - self.origin_y) / res)
        col1 = math.floor((xmax - self.origin_x) / res) + 1
        row1 = math.floor((ymax - self.origin_y) / res) + 1
        return Window(row0, col0, row1, col1).intersect(self.full)

    def cell_centres(
        self, window: Window | None = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """``(xs, ys)``: world x of the window's column centres and y of its row centres."""
        w = window or self.full
        res = self.resolution_m
        xs = self.origin_x + (np.arange(w.col0, w.col1, dtype=np.float64) + 0.5) * res
        ys = self.origin_y + (np.arange(w.row0, w.row1, dtype=np.float64) + 0.5) * res
        return xs, ys


@dataclass(frozen=True, eq=False, slots=True)
class OccupancyGrid:
    """One skill map of one storey: a frame and ``(height, width) int8`` values (0, 100, -1).

    ``elevation_m`` is the storey's elevation: the z the map's heights are measured from.
    """

    frame: GridFrame
    data: GridData
    storey: str
    skill: str
    elevation_m: float = 0.0

    def __post_init__(self) -> None:
        if self.data.shape != self.frame.shape:
            msg = f"Grid data has shape {self.data.shape}, but its frame is {self.frame.shape}."
            raise MapError(msg)
        if self.data.dtype != np.int8:
            msg = f"Grid data must be int8, got {self.data.dtype}."
            raise MapError(msg)

    def occupied(self) -> npt.NDArray[np.bool_]:
        occupied: npt.NDArray[np.bool_] = self.data == OCCUPIED
        return occupied
