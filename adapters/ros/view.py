"""The floor a sensor saw: its field of view cut by the building's structure, as a 2D visibility polygon.

Rays fan out over the horizontal field of view from the sensor's position (at least ``rays``, and
dense enough that neighbours are a cell apart at full range, so no wall fits between two); each
is marched over an occupancy grid of the structure (e.g. the localization map: walls at lidar height)
at half a cell's step and stops at the first occupied cell or the grid's edge, else at ``range_m``.
Each ray then reaches no farther than its neighbours (conservative: what lies between two rays is
claimed only as far as both saw), and runs of rays of one reach keep only their ends and a ray every 22.5°
(the chord lies inside). The polygon is the sensor's position followed by the rays' ends in angular order
(star-shaped around the sensor, hence simple; for a full 360° view the ends alone). Everything at
once in numpy: ``(rays, samples)``.

Example::

    polygon = visibility_polygon(grid, (2.0, 3.0), heading_rad=0.0, fov_rad=1.2, range_m=6.0)
    # ((2.0, 3.0), (x1, y1), ..., (xn, yn))
"""

from __future__ import annotations

import math

import numpy as np

from twin.maps.grid import OccupancyGrid

__all__ = ["OCCUPIED_AT", "polygon_area", "visibility_polygon"]

MAX_RAYS = 4096
"""At most this many rays, however wide and long the view."""
MAX_CHORD_RAD = math.pi / 8
"""Merged rays span at most this angle (the chord of a 5 m arc over it is 10 cm inside)."""
OCCUPIED_AT = 50
"""Cells at or above this value block a ray (``nav_msgs/OccupancyGrid``: 100 occupied, 0 free)."""


def visibility_polygon(
    grid: OccupancyGrid | None,
    origin_xy: tuple[float, float],
    *,
    heading_rad: float,
    fov_rad: float,
    range_m: float,
    rays: int = 64,
) -> tuple[tuple[float, float], ...]:
    """The floor polygon the sensor at ``origin_xy`` (map frame) looking along ``heading_rad`` saw.

    ``grid`` None: nothing occludes (the field of view's sector). A ray's end is never closer than one
    cell (or 5 cm) to the sensor, so a sensor standing in an occupied cell still gives a simple polygon.
    """
    ox, oy = float(origin_xy[0]), float(origin_xy[1])
    full = fov_rad >= 2 * math.pi - 1e-9
    span = 2 * math.pi if full else fov_rad
    res = grid.frame.resolution_m if grid is not None else 0.05
    count = max(int(rays), 3)
    if grid is not None:  # dense enough that neighbouring rays are a cell apart at full range
        count = min(max(count, math.ceil(span * range_m / res) + 1), MAX_RAYS)
    angles = (
        heading_rad - span / 2 + span * (np.arange(count) / count if full else np.linspace(0.0, 1.0, count))
    )
    near = max(res, 0.05)
    if grid is None:
        reach = np.full(count, range_m)
    else:
        step = res / 2
        dist = np.arange(near, range_m + step, step)[None, :]  # (1, k)
        xs = ox + np.cos(angles)[:, None] * dist  # (rays, k)
        ys = oy + np.sin(angles)[:, None] * dist
        f = grid.frame
        cols = np.floor((xs - f.origin_x) / res).astype(np.int64)
        rows = np.floor((ys - f.origin_y) / res).astype(np.int64)
        inside = (cols >= 0) & (cols < f.width) & (rows >= 0) & (rows < f.height)
        blocked = ~inside
        blocked[inside] = grid.data[rows[inside], cols[inside]] >= OCCUPIED_AT
        hit = blocked.any(axis=1)
        first = blocked.argmax(axis=1)
        reach = np.where(hit, np.maximum(dist[0, first] - step, near), range_m)
        reach = np.minimum(reach, range_m)
        # conservative between rays: each ray no farther than its neighbours
        padded = np.concatenate([reach[-1:], reach, reach[:1]]) if full else np.pad(reach, 1, mode="edge")
        reach = np.minimum(np.minimum(padded[:-2], padded[1:-1]), padded[2:])
    keep = np.ones(count, dtype=bool)  # runs of one reach: their ends (the chord between is closer),
    if count > 2:  # and a ray every MAX_CHORD_RAD so that no chord swings round the sensor
        same = (reach[1:-1] == reach[:-2]) & (reach[1:-1] == reach[2:])
        keep[1:-1] = ~same
        keep[:: max(1, int(MAX_CHORD_RAD / (span / count)))] = True
    angles, reach = angles[keep], reach[keep]
    if full and len(reach) < 3:  # a full circle of one reach: a triangle inside it is still inside
        angles = heading_rad + 2 * math.pi * np.arange(3) / 3
        reach = np.full(3, float(reach.min()) / 2)
    ends = np.stack([ox + np.cos(angles) * reach, oy + np.sin(angles) * reach], axis=1)
    points = [(float(x), float(y)) for x, y in ends]
    return tuple(points) if full else ((ox, oy), *points)


def polygon_area(polygon: tuple[tuple[float, float], ...]) -> float:
    """The area of a simple polygon (shoelace), m²."""
    if len(polygon) < 3:
        return 0.0
    p = np.asarray(polygon, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)
