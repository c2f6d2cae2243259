"""One-way lanes: the configured one-way stretches (``one_way`` of a routes skill) turn the lanes
along them into lanes that go one way only.

A lane is along a stretch when both its ends lie within the stretch's ``within_m`` of its segment
and it runs within 45 degrees of the segment's direction (a lane across a corridor stays two-way).
Such a lane becomes ``one_way``, its ends ordered so that it goes the segment's way. A one-way door
(``door``) makes the lane carrying that door's name go only towards its end nearer (x2, y2). A
stretch or door that no lane of the storeys it names follows makes a note.

Example::

    storeys, notes = apply_one_way(storeys, routes.one_way)
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from twin.config.routes import OneWay
from twin.records import FloatArray
from twin.routes.graph import RouteLane, StoreyRoutes

__all__ = ["along", "apply_one_way", "through"]

COS_ALONG = float(np.cos(np.radians(45.0)))
"""A lane within this angle of a stretch's direction runs along it."""


def along(ends: FloatArray, stretch: OneWay) -> tuple[np.ndarray, np.ndarray]:
    """Which lanes run along ``stretch``, and which of those run against its direction.

    ``ends``: ``(n, 2, 2)`` float64, each lane's two ends (x, y). Returns two ``(n,)`` bool arrays."""
    p = np.array([stretch.x1, stretch.y1])
    d = np.array([stretch.x2, stretch.y2]) - p
    length = float(np.hypot(*d))
    u = d / length
    rel = ends - p  # (n, 2, 2)
    t = np.clip(rel @ u, 0.0, length)  # (n, 2): each end's foot on the segment
    gap = np.linalg.norm(rel - t[..., None] * u, axis=-1)  # (n, 2)
    lane = ends[:, 1] - ends[:, 0]
    norm = np.linalg.norm(lane, axis=-1)
    cos = np.divide(lane @ u, norm, out=np.zeros(len(ends)), where=norm > 0)
    hit = (gap <= stretch.within_m).all(axis=1) & (np.abs(cos) >= COS_ALONG)
    return hit, hit & (cos < 0)


def apply_one_way(
    storeys: Sequence[StoreyRoutes], stretches: Sequence[OneWay]
) -> tuple[tuple[StoreyRoutes, ...], list[str]]:
    """``storeys`` with the lanes along ``stretches`` made one-way, and a note per stretch along
    which no lane runs."""
    if not stretches:
        return tuple(storeys), []
    used = np.zeros(len(stretches), dtype=np.bool_)
    out: list[StoreyRoutes] = []
    for s in storeys:
        if not s.lanes:
            out.append(s)
            continue
        xy = np.array([(v.x, v.y) for v in s.vertices], dtype=np.float64)
        ab = np.array([(lane.a, lane.b) for lane in s.lanes], dtype=np.intp)
        ends = xy[ab]  # (n, 2, 2)
        one_way = np.zeros(len(ab), dtype=np.bool_)
        flip = np.zeros(len(ab), dtype=np.bool_)
        for k, stretch in enumerate(stretches):
            if stretch.storey is not None and stretch.storey != s.storey:
                continue
            hit, against = along(ends, stretch) if stretch.door is None else through(s, ends, stretch)
            hit &= ~one_way  # the first stretch a lane is along decides its way
            one_way |= hit
            flip |= hit & against
            used[k] |= bool(hit.any())
        if not one_way.any():
            out.append(s)
            continue
        lanes = [
            RouteLane(lane.b, lane.a, lane.door, True) if f else replace(lane, one_way=True) if o else lane
            for lane, o, f in zip(s.lanes, one_way.tolist(), flip.tolist(), strict=True)
        ]
        out.append(replace(s, lanes=tuple(lanes)))
    notes = [
        (
            f"one_way door {w.door}{f' on {w.storey}' if w.storey else ''}: no lane passes it"
            if w.door is not None
            else f"one_way ({w.x1:g}, {w.y1:g}) -> ({w.x2:g}, {w.y2:g})"
            f"{f' on {w.storey}' if w.storey else ''}: no lane runs along it"
        )
        for w, hit in zip(stretches, used.tolist(), strict=True)
        if not hit
    ]
    return tuple(out), notes


def through(s: StoreyRoutes, ends: FloatArray, door: OneWay) -> tuple[np.ndarray, np.ndarray]:
    """Which lanes of ``s`` pass ``door.door`` (by the name they carry: the door's RMF name, or its
    IFC name as the graph sanitises it), and which of those run away from (x2, y2)."""
    names = {door.door, _UNSAFE.sub("_", door.door or "").strip("_")}
    hit = np.array([lane.door in names and lane.door != "" for lane in s.lanes], dtype=np.bool_)
    target = np.array([door.x2, door.y2])
    to_a, to_b = (np.linalg.norm(ends[:, k] - target, axis=-1) for k in (0, 1))
    return hit, hit & (to_a < to_b)


_UNSAFE = re.compile(r"[^A-Za-z0-9_]+")
