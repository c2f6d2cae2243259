"""The surface point nearest each touched voxel's centre, and its squared distance (cell units).

For each (triangle, voxel) pair that :func:`twin.maps.voxels.touched_pairs` found: the point of the
triangle inside the voxel's closed box nearest the box's centre. Where the pair's hint says the voxel's
column lies inside the triangle, that is the centre's projection on the triangle's plane (exactly the
centre moved onto a face in a grid plane); elsewhere the triangle is clipped to the box and the nearest
point of the clipped polygon is sought. A sliver whose area is rounding is taken as its edges
(``TOLERANCES.sliver_sin2``).

Example::

    tri, ijk, hint = touched_pairs(cells, lo=(0, 0, -1), hi=(200, 150, 30), w_band=(-0.5, 30.0))
    q, d2 = nearest_points_of(cells, tri, ijk, w_band=(-0.5, 30.0), hint=hint)   # a point per pair
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from twin.maps.voxels import _LEVEL, _PLANE, FloatArray, IntArray, _boxes, _cross, _dot
from twin.tolerances import TOLERANCES


def _closest_on_triangle(p: FloatArray, a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """The point of each triangle ``abc`` nearest ``p``: ``p``'s projection on the plane when it lies in
    the triangle, else the nearest point of its edges. (Not by barycentric regions: their products cancel
    on a sliver, a long thin triangle of a tessellated curve, whose point would move along it by the
    rounding of its vertices, 2e-8 cells for 1e-11; the projection and the edges are well conditioned, and
    meet where a point crosses an edge, so a wrong side within rounding moves it by rounding only.)"""
    ab, ac = b - a, c - a
    n = _cross(ab, ac)
    nn = _dot(n, n)
    corners = np.stack([a, b, c], axis=1)
    # degenerate triangles (and slivers whose area is rounding: sin^2 of the angle at a below 1e-12,
    # under a micrometre of width per metre): their nearest edge
    ok = nn > TOLERANCES.sliver_sin2 * _dot(ab, ab) * _dot(ac, ac)
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = p - n * (_dot(p - a, n) / np.where(ok, nn, 1.0))[:, None]
    inside = ok.copy()
    for v0, v1 in ((a, b), (b, c), (c, a)):
        inside &= _dot(_cross(v1 - v0, proj - v0), n) >= 0
    out = np.where(inside[:, None], proj, 0.0)
    rest = ~inside
    if rest.any():
        out[rest] = _closest_on_segments(p[rest], corners[rest], np.full(int(rest.sum()), 3))
    return out


def _closest_on_segments(p: FloatArray, poly: FloatArray, count: IntArray) -> FloatArray:
    """The point of each closed polyline loop ``poly[:count]`` (its edges) nearest ``p``."""
    m, k = poly.shape[:2]
    a = poly
    b = _next_vertices(poly, count)
    ab = b - a
    ll = _dot(ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.where(ll > 0, _dot(p[:, None, :] - a, ab) / ll, 0.0), 0.0, 1.0)
    q = a + ab * t[..., None]
    d = _dot(q - p[:, None, :], q - p[:, None, :])
    d = np.where(np.arange(k)[None, :] < count[:, None], d, np.inf)
    best = np.argmin(d, axis=1)
    out: FloatArray = q[np.arange(m), best]
    return out


def _next_vertices(poly: FloatArray, count: IntArray) -> FloatArray:
    """Per polygon ``poly[:count]``: each vertex's successor around it (beyond ``count``: anything)."""
    nb = np.roll(poly, -1, axis=1)
    rows = np.flatnonzero(count > 0)
    nb[rows, count[rows] - 1] = poly[rows, 0]
    return nb


def _clip(tri: FloatArray, lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, IntArray]:
    """Each triangle cut by its closed box (Sutherland-Hodgman): ``(polygons (m, 9, 3), counts)``
    (zeros beyond each count)."""
    m = len(tri)
    poly = np.zeros((m, 3, 3))
    poly[:] = tri
    count = np.full(m, 3, dtype=np.int64)
    for axis in range(3):
        for bound, sign in ((lo[:, axis], 1.0), (hi[:, axis], -1.0)):
            k = poly.shape[1]
            valid = np.arange(k)[None, :] < count[:, None]
            cur = poly
            nb = _next_vertices(poly, count)
            dc = sign * (cur[:, :, axis] - bound[:, None])
            dn = sign * (nb[:, :, axis] - bound[:, None])
            cin, nin = dc >= 0, dn >= 0
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(dc != dn, dc / (dc - dn), 0.0)
            cross = cur + (nb - cur) * t[..., None]
            cross[:, :, axis] = np.where(cin != nin, bound[:, None], cross[:, :, axis])
            out = np.empty((m, 2 * k, 3))
            keep = np.empty((m, 2 * k), dtype=np.bool_)
            out[:, 0::2], keep[:, 0::2] = cur, valid & cin
            out[:, 1::2], keep[:, 1::2] = cross, valid & (cin != nin)
            # the kept vertices first, in order (at most 9: a triangle cut by a box has up to 9)
            pos = np.cumsum(keep, axis=1) - 1
            keep &= pos < 9
            r, c = np.nonzero(keep)
            poly = np.zeros((m, min(9, 2 * k), 3))
            poly[r, pos[r, c]] = out[r, c]
            count = keep.sum(axis=1)
    if poly.shape[1] < 9:
        poly = np.concatenate([poly, np.zeros((m, 9 - poly.shape[1], 3))], axis=1)
    return poly, count


def nearest_points(
    tri: FloatArray, ijk: IntArray, *, w_band: tuple[float, float], hint: IntArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """For each touching pair: the point of the triangle within the voxel's (closed) box nearest the
    box's centre, and its squared distance (cell units). ``tri`` is ``(m, 3, 3)``, one per voxel;
    ``hint`` (from :func:`touched_pairs`) lets the pairs whose column lies inside the triangle skip
    the general search: the centre's projection on the plane is then the point when it is in the box."""
    return nearest_points_of(tri, np.arange(len(tri)), ijk, w_band=w_band, hint=hint)


def nearest_points_of(
    cells: FloatArray,
    t: IntArray,
    ijk: IntArray,
    *,
    w_band: tuple[float, float],
    hint: IntArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """:func:`nearest_points` of the pairs (triangle ``cells[t]``, voxel ``ijk``), gathering only the
    triangles a pair's hint does not spare."""
    lo, hi = _boxes(ijk, w_band)
    centre = 0.5 * (lo + hi)
    q = centre.copy()
    rest = np.ones(len(t), dtype=np.bool_)
    if hint is not None:
        level = np.flatnonzero((hint >= 0) & (hint < _LEVEL))  # in a face in a grid plane: the centre onto it
        if len(level):
            axis = hint[level]
            q[level, axis] = cells[t[level], 0, axis]
            rest[level] = False
        plane = np.flatnonzero(hint == _PLANE)
        if len(plane):
            tp, c = cells[t[plane]], centre[plane]
            n = _cross(tp[:, 1] - tp[:, 0], tp[:, 2] - tp[:, 0])
            proj = c - n * (_dot(c - tp[:, 0], n) / _dot(n, n))[:, None]
            inside = ((proj >= lo[plane]) & (proj <= hi[plane])).all(axis=1)
            q[plane[inside]] = proj[inside]
            rest[plane[inside]] = False
        flat = np.flatnonzero(hint >= _LEVEL)  # a face in a grid plane, at the voxel's border
        if len(flat):
            axis = hint[flat] - _LEVEL
            got, found = _nearest_level(cells[t[flat]], axis, lo[flat], hi[flat], centre[flat])
            q[flat[found]] = got[found]
            rest[flat[found]] = False
    r = np.flatnonzero(rest)
    if len(r):
        # from the voxel's corner (exact: whole cells off): the search's rounding is that of small
        # numbers, not of the building's distance from the origin (its 10 km)
        corner = ijk[r].astype(np.float64)
        local = cells[t[r]] - corner[:, None, :]
        q[r] = _nearest_general(local, lo[r] - corner, hi[r] - corner, centre[r] - corner) + corner
    q = np.clip(q, lo, hi)
    return q, _squared_distance(q, centre)


def _squared_distance(q: FloatArray, centre: FloatArray) -> FloatArray:
    diff = q - centre
    return _dot(diff, diff)


def distance_to_centres(q: FloatArray, ijk: IntArray, *, w_band: tuple[float, float]) -> FloatArray:
    """Each point's squared distance to its voxel's centre (cell units), as :func:`nearest_points`
    gives it (the same numbers)."""
    lo, hi = _boxes(ijk, w_band)
    return _squared_distance(q, 0.5 * (lo + hi))


def _nearest_level(
    tri: FloatArray, axis: IntArray, lo: FloatArray, hi: FloatArray, centre: FloatArray
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """For triangles level along ``axis`` (every vertex's coordinate there is one value, within the
    box): the nearest point is a 2D one, lifted to that level. The centre itself when the triangle
    covers it; else, the box's centre being inside the box, the nearest point of the triangle's edges
    cut to the box (none may be found through rounding: ``found`` False, for the general search)."""
    m = len(tri)
    rows = np.arange(m)
    p, q = (axis + 1) % 3, (axis + 2) % 3
    up, uq = tri[rows, :, p], tri[rows, :, q]  # (m, 3) the vertices in 2D
    cp, cq = centre[rows, p], centre[rows, q]
    lo_p, hi_p, lo_q, hi_q = lo[rows, p], hi[rows, p], lo[rows, q], hi[rows, q]
    best = np.full(m, np.inf)
    bp, bq = cp.copy(), cq.copy()
    sides = np.zeros((m, 3))
    for i in range(3):
        ap, aq = up[:, i], uq[:, i]
        ep, eq = up[:, (i + 1) % 3] - ap, uq[:, (i + 1) % 3] - aq
        sides[:, i] = ep * (cq - aq) - eq * (cp - ap)
        # the edge cut to the closed box (Liang-Barsky), then its point nearest the centre
        t0, t1 = np.zeros(m), np.ones(m)
        with np.errstate(divide="ignore", invalid="ignore"):
            for a0, e, b_lo, b_hi in ((ap, ep, lo_p, hi_p), (aq, eq, lo_q, hi_q)):
                moving = e != 0
                u = np.where(moving, (b_lo - a0) / np.where(moving, e, 1.0), -np.inf)
                v = np.where(moving, (b_hi - a0) / np.where(moving, e, 1.0), np.inf)
                enter, leave = np.minimum(u, v), np.maximum(u, v)
                t0, t1 = np.maximum(t0, enter), np.minimum(t1, leave)
                outside = ~moving & ((a0 < b_lo) | (a0 > b_hi))
                t0 = np.where(outside, np.inf, t0)
            ll = ep * ep + eq * eq
            s = np.where(ll > 0, ((cp - ap) * ep + (cq - aq) * eq) / np.where(ll > 0, ll, 1.0), 0.0)
        s = np.clip(s, t0, t1)
        xp, xq = ap + s * ep, aq + s * eq
        dist = (xp - cp) ** 2 + (xq - cq) ** 2
        better = (t0 <= t1) & (dist < best)
        best = np.where(better, dist, best)
        bp, bq = np.where(better, xp, bp), np.where(better, xq, bq)
    covered = ((sides >= 0).all(axis=1) | (sides <= 0).all(axis=1)) & (np.abs(sides).max(axis=1) > 0)
    bp, bq = np.where(covered, cp, bp), np.where(covered, cq, bq)
    out = centre.copy()
    out[rows, p], out[rows, q] = bp, bq
    out[rows, axis] = tri[rows, 0, axis]
    return out, covered | np.isfinite(best)


def _nearest_general(tri: FloatArray, lo: FloatArray, hi: FloatArray, centre: FloatArray) -> FloatArray:
    """:func:`nearest_points` without hints (before the clamp to the box). A degenerate triangle's plane
    is not finite: its rows take their polygon's edges (quietly)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _nearest_general_rows(tri, lo, hi, centre)


def _nearest_general_rows(tri: FloatArray, lo: FloatArray, hi: FloatArray, centre: FloatArray) -> FloatArray:
    q = _closest_on_triangle(centre, tri[:, 0], tri[:, 1], tri[:, 2])
    outside = ~((q >= lo) & (q <= hi)).all(axis=1)
    if outside.any():
        o = np.flatnonzero(outside)
        # the box grown by a rounding margin, so that a contact at a point or along an edge survives
        # the clipping's rounding (the result is clamped to the box below)
        grow = 1e-10 * (1.0 + np.abs(tri[o].reshape(len(o), -1)).max(axis=1))[:, None]
        poly, count = _clip(tri[o], lo[o] - grow, hi[o] + grow)
        c = centre[o]
        n = _cross(tri[o, 1] - tri[o, 0], tri[o, 2] - tri[o, 0])
        nn = _dot(n, n)
        with np.errstate(divide="ignore", invalid="ignore"):
            proj = c - n * (_dot(c - tri[o, 0], n) / nn)[:, None]
        k = poly.shape[1]
        idx = np.arange(k)[None, :]
        nb = _next_vertices(poly, count)
        side = _dot(_cross(nb - poly, proj[:, None, :] - poly), n[:, None, :])
        # a polygon with no area (the triangle touches the box at a point or along a segment): its edges
        area = _cross(poly, nb)
        area = np.where((idx < count[:, None])[:, :, None], area, 0.0).sum(axis=1)
        extent = 1.0 + np.abs(poly.reshape(len(o), -1)).max(axis=1)
        flat = _dot(area, n) <= 1e-12 * np.sqrt(nn) * extent**2
        inside = np.where(idx < count[:, None], side >= 0, True).all(axis=1) & (count >= 3) & (nn > 0) & ~flat
        edge = _closest_on_segments(c, poly, count)
        best = np.where(inside[:, None], proj, edge)
        empty = count == 0  # only float noise: the triangle touches at a point or an edge
        best[empty] = q[o][empty]
        q[o] = best
    return q
