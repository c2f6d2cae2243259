"""Which voxels a set of triangles touches, exactly (the surface point nearest each voxel's centre:
:mod:`twin.maps.nearest`).

Coordinates here are *cell coordinates*: world metres minus the grid origin, divided by the voxel size,
computed once per vertex in float64 (``(x - origin) / resolution``), a coordinate within 1 um of a grid
plane (or of the band's ends) being exactly on it (:func:`twin.maps.grid.grid_coordinates`, applied by
:meth:`twin.maps.points.PointsPlan.cells`): ties with the grid are decided in the model's coordinates,
not by the float rounding of that division. Voxel ``(i, j, k)`` is the
half-open box ``[i, i+1) x [j, j+1) x [max(k, w_lo), min(k+1, w_hi))``: the cell, cut by the height
band ``[w_lo, w_hi)``. A triangle (a closed set) *touches* a voxel when they share a point.

Points maps test the voxel with its lower faces moved out and its upper faces moved in by a fraction of
a micrometre (``shift``, from ``TOLERANCES.voxel_out_m`` and ``voxel_in_m``): a vertex coordinate is
on a grid plane or more than ``TOLERANCES.grid_m`` from one, so the move changes nothing for vertices,
but a slanted surface that passes exactly through a voxel's edge or corner with its vertices off the
grid (a 30 degree roof through a grid line, a 45 degree wall through grid corners) is then clear of the
moved box or into it by nanometres or more, not by the rounding of its vertices, which moving the
building changes. On such a tie the verdict is the half-open rule's on the exact geometry unless the
surface or edge is within 0.35 degrees of a grid plane or axis (the moves' ratio, 161.8, is of no small
whole numbers, so that no simple slope through a grid corner passes through a moved corner).

The test is the separating axis theorem for a triangle and a box (13 axes), with two refinements that
make it exact rather than approximate:

- half-open boxes: a triangle that meets a box only on its upper faces (``x = i+1`` ...) does not
  touch it; on an axis, that is a projection touching the box's interval at an end that moves inward
  when the upper faces move in (the limit of closed boxes shrunk by ``d -> 0+``);
- rounding: the three box axes compare the vertices themselves (exact); on the ten other axes, a
  projection within a rounding bound of a tie is decided again in exact rational arithmetic
  (:class:`_ExactTriangle`, Python integers, each triangle made exact once), so float noise never adds
  or drops a voxel.

Candidates are enumerated per triangle by columns along its dominant normal axis, per strip of its
projection (a big slanted triangle costs its area in voxels, not its bounding box's volume), in batches
of bounded size. Most voxels of large faces need no test: a column whose square lies inside the
triangle's projection beyond rounding holds the voxels the plane's range crosses beyond rounding (for
a face in a grid plane, exactly one, given in runs of columns), and a triangle within one cell touches
that voxel only; the test decides the rest. Those certain pairs carry a *hint* that makes their point
cheaper (:func:`twin.maps.nearest.nearest_points`: the centre's projection on the plane).

Example::

    tri, ijk, hint = touched_pairs(cells, lo=(0, 0, -1), hi=(200, 150, 30), w_band=(-0.5, 30.0))
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from twin.tolerances import TOLERANCES

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_BATCH = 150_000
"""Candidate (triangle, voxel) pairs tested at once (bounds the memory of a batch to ~100 MB)."""
_NO_HINT = -2
"""Hints per touching pair: ``_NO_HINT``; ``_PLANE``: certain, the column's square inside the
triangle's projection (over it, the triangle is its plane); ``0, 1, 2``: that, and the triangle is
level along that (dominant) axis; ``_INSIDE``: certain, the triangle lies in the voxel; ``_LEVEL +
0, 1, 2``: not certain (tested), the triangle level along that axis."""
_PLANE = -1
_INSIDE = -3
_LEVEL = 3


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.float64)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _min3(a: FloatArray) -> FloatArray:
    """The minimum over axis 1 of ``(m, 3, ...)`` (element-wise: numpy's reductions over a short axis
    are slow)."""
    return np.minimum(np.minimum(a[:, 0], a[:, 1]), a[:, 2])


def _max3(a: FloatArray) -> FloatArray:
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2])


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.asarray(a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2])


def _coordinate(cells: FloatArray, axis: IntArray) -> FloatArray:
    """Per triangle of ``cells (n, 3, 3)``: its vertices' coordinate ``axis[t]`` (``(n, 3)``)."""
    a = axis[:, None]
    out: FloatArray = np.where(a == 0, cells[:, :, 0], np.where(a == 1, cells[:, :, 1], cells[:, :, 2]))
    return out


# --- candidates ------------------------------------------------------------------------------------
def _columns(
    cells: FloatArray, lo: IntArray, hi: IntArray
) -> tuple[IntArray, IntArray, IntArray, IntArray, IntArray]:
    """Per triangle: its dominant axis ``d``, the other two ``p, q``, and its index ranges per axis
    (``first``, ``last`` inclusive, clipped to ``[lo, hi)``)."""
    n = _cross(cells[:, 1] - cells[:, 0], cells[:, 2] - cells[:, 0])
    a0, a1, a2 = np.abs(n[:, 0]), np.abs(n[:, 1]), np.abs(n[:, 2])
    d = np.where((a0 >= a1) & (a0 >= a2), 0, np.where(a1 >= a2, 1, 2)).astype(np.int64)  # argmax
    p = (d + 1) % 3
    q = (d + 2) % 3
    first = np.maximum(np.floor(_min3(cells)).astype(np.int64), lo)
    last = np.minimum(np.floor(_max3(cells)).astype(np.int64), hi - 1)
    return d, p, q, first, last


def _strips(
    vp: FloatArray,
    vq: FloatArray,
    *,
    ok: npt.NDArray[np.bool_],
    span_p: IntArray,
    first_p: IntArray,
    first_q: IntArray,
    last_q: IntArray,
    big: FloatArray,
    slack: float,
) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Per strip ``a <= p <= a + 1`` of each triangle's projection ``(vp, vq)``: ``(triangle, a, first
    column b, columns)``, the columns covering the triangle's q range over the strip, widened beyond
    rounding (a superset of the columns whose closed square meets the triangle)."""
    sel = np.flatnonzero(ok)
    n = np.where(ok, span_p, 0)[sel]
    ts = np.repeat(sel, n)
    sa = first_p[ts] + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    margin = 1e-6 * (big[ts] + 2.0) + slack
    s_lo, s_hi = sa - margin, sa + 1.0 + margin
    q_lo = np.full(len(ts), np.inf)
    q_hi = np.full(len(ts), -np.inf)
    for i in range(3):
        p0, p1 = vp[ts, i], vp[ts, (i + 1) % 3]
        q0, q1 = vq[ts, i], vq[ts, (i + 1) % 3]
        lo_p, hi_p = np.minimum(p0, p1), np.maximum(p0, p1)
        meets = (lo_p <= s_hi) & (hi_p >= s_lo)
        dp = p1 - p0
        # an edge nearly along q (its slope ill-conditioned): its whole q range
        steep = np.abs(dp) <= margin
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.where(steep, 0.0, 1.0 / np.where(steep, 1.0, dp))
            t0 = np.clip((np.maximum(lo_p, s_lo) - p0) * inv, 0.0, 1.0)
            t1 = np.clip((np.minimum(hi_p, s_hi) - p0) * inv, 0.0, 1.0)
        dq = q1 - q0
        qa = np.where(steep, q0, q0 + t0 * dq)
        qb = np.where(steep, q1, q0 + t1 * dq)
        q_lo = np.where(meets, np.minimum(q_lo, np.minimum(qa, qb)), q_lo)
        q_hi = np.where(meets, np.maximum(q_hi, np.maximum(qa, qb)), q_hi)
    has = q_lo <= q_hi
    first_b = np.maximum(np.floor(np.where(has, q_lo - margin, 0.0)).astype(np.int64), first_q[ts])
    last_b = np.minimum(np.floor(np.where(has, q_hi + margin, -1.0)).astype(np.int64), last_q[ts])
    nb = np.where(has, np.maximum(last_b - first_b + 1, 0), 0)
    return ts, sa, first_b, nb


def _level_runs(
    vp: FloatArray,
    vq: FloatArray,
    ts: IntArray,
    sa: IntArray,
    *,
    first_b: IntArray,
    last_b: IntArray,
    big: FloatArray,
    slack: float,
) -> tuple[IntArray, IntArray]:
    """Per strip ``a <= p <= a + 1`` of triangle ``ts``: the run ``[r0, r1]`` of its columns (within
    ``[first_b, last_b]``) whose closed squares lie inside the triangle's projection beyond rounding
    (empty: ``r0 > r1``). Over a strip, the projection's lower boundary is convex and its upper one
    concave: they are checked at the strip's two sides."""
    margin = 1e-6 * (big[ts] + 2.0) + slack
    p_lo, p_hi = _min3(vp[ts]), _max3(vp[ts])
    inner = (sa >= p_lo + margin) & (sa + 1.0 <= p_hi - margin)
    low = np.full(len(ts), -np.inf)
    high = np.full(len(ts), np.inf)
    for x in (sa.astype(np.float64), sa + 1.0):
        lo_x = np.full(len(ts), np.inf)
        hi_x = np.full(len(ts), -np.inf)
        for i in range(3):
            p0, p1 = vp[ts, i], vp[ts, (i + 1) % 3]
            q0, q1 = vq[ts, i], vq[ts, (i + 1) % 3]
            dp = p1 - p0
            # an edge nearly along q is at the projection's side, beyond the strip (inner)
            use = (np.abs(dp) > margin) & (x >= np.minimum(p0, p1)) & (x <= np.maximum(p0, p1))
            with np.errstate(divide="ignore", invalid="ignore"):
                qx = q0 + (x - p0) / np.where(use, dp, 1.0) * (q1 - q0)
            lo_x = np.where(use, np.minimum(lo_x, qx), lo_x)
            hi_x = np.where(use, np.maximum(hi_x, qx), hi_x)
        low, high = np.maximum(low, lo_x), np.minimum(high, hi_x)
    inner &= np.isfinite(low) & np.isfinite(high)
    r0 = np.maximum(np.ceil(np.where(inner, low + margin, 0.0)).astype(np.int64), first_b)
    r1 = np.minimum(np.floor(np.where(inner, high - margin, 0.0)).astype(np.int64) - 1, last_b)
    return np.where(inner, r0, 1), np.where(inner, r1, 0)


def _split_level_runs(
    vp: FloatArray,
    vq: FloatArray,
    strips: tuple[IntArray, IntArray, IntArray, IntArray],
    *,
    axes: tuple[IntArray, IntArray, IntArray],
    level: npt.NDArray[np.bool_],
    value: FloatArray,
    frame: tuple[IntArray, IntArray],
    w_band: tuple[float, float],
    big: FloatArray,
    slack: float,
) -> tuple[IntArray, IntArray, IntArray, IntArray, IntArray, IntArray]:
    """The voxels of the runs of columns inside level triangles (one each, at the level's layer, certain:
    ``(triangle, (m, 3) voxel)``), and the strips' other columns as ranges ``(triangle, a, first b,
    columns)`` (a strip with a run: the columns before it and those after it)."""
    ts, sa, b0, nb = strips
    d, p, q = axes
    lo, hi = frame
    idx = np.flatnonzero(level[ts] & (nb > 0))
    t, a, first = ts[idx], sa[idx], b0[idx]
    last = first + nb[idx] - 1
    r0, r1 = _level_runs(vp, vq, t, a, first_b=first, last_b=last, big=big, slack=slack)
    c = value[t]  # the level (exactly every vertex's d coordinate)
    k = np.floor(c).astype(np.int64)
    dt, pt, qt = d[t], p[t], q[t]
    ok = (k >= lo[dt]) & (k <= hi[dt] - 1)
    ok &= (dt != 2) | ((c >= w_band[0]) & (c < w_band[1]))  # the voxel, cut by the band, holds c
    ok &= (pt != 2) | ((a >= w_band[0]) & (a + 1.0 <= w_band[1]))  # squares whole in the band
    b_min = math.ceil(w_band[0]) if math.isfinite(w_band[0]) else np.iinfo(np.int64).min
    b_max = math.floor(w_band[1]) - 1 if math.isfinite(w_band[1]) else np.iinfo(np.int64).max
    zq = qt == 2
    r0 = np.where(zq, np.maximum(r0, b_min), r0)
    r1 = np.where(zq, np.minimum(r1, b_max), r1)
    n_run = np.where(ok, np.maximum(r1 - r0 + 1, 0), 0)
    total = int(n_run.sum())
    rs = np.repeat(np.arange(len(idx)), n_run)
    b = r0[rs] + np.arange(total) - np.repeat(np.cumsum(n_run) - n_run, n_run)
    ijk = np.empty((total, 3), dtype=np.int64)
    dr, pr, ar, kr = dt[rs], pt[rs], a[rs], k[rs]
    for axis in range(3):
        ijk[:, axis] = np.where(dr == axis, kr, np.where(pr == axis, ar, b))
    # the other columns: before the run (all of them without one) and after it
    has = n_run > 0
    nb = nb.copy()
    nb[idx] = np.where(has, r0 - first, nb[idx])
    after = np.flatnonzero(has)
    rest = (
        np.concatenate([ts, t[after]]),
        np.concatenate([sa, a[after]]),
        np.concatenate([b0, r1[after] + 1]),
        np.concatenate([nb, last[after] - r1[after]]),
    )
    return t[rs], ijk, *rest


def _batches(counts: IntArray) -> Iterator[IntArray]:
    """Consecutive runs of indices whose ``counts`` add up to about ``_BATCH`` (at least one index a run)."""
    cum = np.cumsum(counts)
    start = 0
    while start < len(counts):
        base = cum[start - 1] if start else 0
        stop = max(int(np.searchsorted(cum, base + _BATCH, side="right")), start + 1)
        yield np.arange(start, stop)
        start = stop


def _candidates(
    cells: FloatArray,
    lo: IntArray,
    hi: IntArray,
    w_band: tuple[float, float] = (-np.inf, np.inf),
    slack: float = 0.0,
) -> Iterator[tuple[IntArray, IntArray, IntArray]]:
    """Batches of ``(triangle index, (m, 3) voxel index, hint)`` pairs: a superset of the touching
    pairs, with a hint where the pair certainly touches (no test needed; see :data:`_NO_HINT`).

    A pair is sure when the column's whole (closed) square lies inside the triangle's projection by
    a margin beyond rounding (over the square, the triangle is its plane), and the plane's range
    over the square meets the voxel's extent along the column beyond rounding too (exactly, for a
    triangle whose dominant coordinate is one value: a face in a grid-aligned plane). Every margin
    is widened by ``slack``, the largest shift of a voxel's faces (see :func:`touched_pairs`): the
    plane's range over a square moved by ``slack`` moves by at most ``2 slack`` (the dominant axis)."""
    if not len(cells):
        return
    d, p, q, first, last = _columns(cells, lo, hi)
    rows = np.arange(len(cells))
    span_p = last[rows, p] - first[rows, p] + 1
    span_q = last[rows, q] - first[rows, q] + 1
    span_d = last[rows, d] - first[rows, d] + 1
    ok = (span_p > 0) & (span_q > 0) & (span_d > 0)
    n = _cross(cells[:, 1] - cells[:, 0], cells[:, 2] - cells[:, 0])
    # per triangle: its coordinates along p, q, d; its plane; its 2D edge normals in (p, q) with the
    # triangle's extent along each (a column whose square lies beyond one holds no voxel of it)
    vp, vq, vd = (_coordinate(cells, axis) for axis in (p, q, d))
    nd, np_all, nq_all = n[rows, d], n[rows, p], n[rows, q]
    c0_all = _dot(n, cells[:, 0])
    t_lo_all, t_hi_all = _min3(vd), _max3(vd)
    reach = np.maximum(np.abs(_min3(cells)), np.abs(_max3(cells)))
    big_all = 1.0 + np.maximum(np.maximum(reach[:, 0], reach[:, 1]), reach[:, 2])
    edge_p = np.roll(vp, -1, axis=1) - vp  # (n, 3): edge i from vertex i to i + 1
    edge_q = np.roll(vq, -1, axis=1) - vq
    m_p, m_q = edge_q, -edge_p  # the edges' normals in (p, q)
    proj = m_p[:, :, None] * vp[:, None, :] + m_q[:, :, None] * vq[:, None, :]  # (n, edge, vertex)
    e_lo = np.minimum(np.minimum(proj[:, :, 0], proj[:, :, 1]), proj[:, :, 2])
    e_hi = np.maximum(np.maximum(proj[:, :, 0], proj[:, :, 1]), proj[:, :, 2])
    e_tol = (np.abs(m_p) + np.abs(m_q)) * (1e-9 * (big_all[:, None] + 2.0) + slack)
    # per edge: contiguous per-triangle arrays (gathered per column below)
    edges = [
        (m_p[:, i].copy(), m_q[:, i].copy(), e_lo[:, i].copy(), e_hi[:, i].copy(), e_tol[:, i].copy())
        for i in range(3)
    ]
    first_p, first_q = first[rows, p], first[rows, q]
    flat_all = np.abs(nd) > 0
    safe_all = np.where(flat_all, nd, 1.0)
    # rounding of the plane (its normal from rounded edges) and of its evaluation, generously: a
    # nearly degenerate triangle's plane is ill-conditioned, and its column is then its full range
    mag_all = np.abs(c0_all) + (np.abs(np_all) + np.abs(nq_all)) * (big_all + 2.0) + big_all**3
    eps_all = 1e-10 * mag_all / np.abs(safe_all) + 1e-9 + 3.0 * slack
    level_all = t_lo_all == t_hi_all  # the dominant coordinate is one value (exactly t_lo)
    lo_d, hi_d = lo[d], hi[d] - 1
    # a triangle within one cell (and the band) touches that voxel only, certainly
    vmin, vmax = _min3(cells), _max3(cells)
    cell = np.floor(vmin)
    single = ok & (cell == np.floor(vmax)).all(axis=1) & (vmin[:, 2] >= w_band[0]) & (vmax[:, 2] < w_band[1])
    if single.any():
        one = np.flatnonzero(single)
        yield one, cell[one].astype(np.int64), np.full(len(one), _INSIDE, dtype=np.int64)
        ok = ok & ~single
    # the columns: per strip p in [a, a+1] of a triangle, the q range of the triangle there (generously
    # rounded); then batches of strips
    ts, sa, b0, nb = _strips(
        vp,
        vq,
        ok=ok,
        span_p=span_p,
        first_p=first_p,
        first_q=first_q,
        last_q=last[rows, q],
        big=big_all,
        slack=slack,
    )
    # faces in a grid plane (level along d): the columns inside them hold one voxel each, certainly,
    # in runs; the other columns are tested below
    if (level_all & flat_all).any():
        run_t, run_ijk, ts, sa, b0, nb = _split_level_runs(
            vp,
            vq,
            (ts, sa, b0, nb),
            axes=(d, p, q),
            level=level_all & flat_all,
            value=t_lo_all,
            frame=(lo, hi),
            w_band=w_band,
            big=big_all,
            slack=slack,
        )
        if len(run_t):
            yield run_t, run_ijk, d[run_t]
    for sel in _batches(nb):
        counts = nb[sel]
        total_cols = int(counts.sum())
        if not total_cols:
            continue
        strip = np.repeat(sel, counts)
        tri = ts[strip]
        a = sa[strip]
        b = b0[strip] + np.arange(total_cols) - np.repeat(np.cumsum(counts) - counts, counts)
        # drop the columns whose square one of the triangle's (projected) edges separates from it
        keep = np.ones(len(tri), dtype=np.bool_)
        inside = np.ones(len(tri), dtype=np.bool_)  # the square inside the triangle's projection
        for mp_all, mq_all, el_all, eh_all, tol_all in edges:
            mp, mq = mp_all[tri], mq_all[tri]
            base_sq = mp * a + mq * b
            sq_lo = base_sq + np.minimum(mp, 0.0) + np.minimum(mq, 0.0)
            sq_hi = base_sq + np.maximum(mp, 0.0) + np.maximum(mq, 0.0)
            tol, el, eh = tol_all[tri], el_all[tri], eh_all[tri]
            keep &= (sq_hi >= el - tol) & (sq_lo <= eh + tol)
            inside &= (sq_lo > el + tol) & (sq_hi < eh - tol)
        tri, a, b, inside = tri[keep], a[keep], b[keep], inside[keep]
        if not len(tri):
            continue
        dt, pt, qt = d[tri], p[tri], q[tri]
        # a square cut by the band (along p or q = z) is not whole: not sure
        pz, qz = pt == 2, qt == 2
        zc = np.where(pz, a, b)
        inside &= ~(pz | qz) | ((zc >= w_band[0]) & (zc + 1 <= w_band[1]))
        # the plane's range of the dominant coordinate over the column's square, cut to the triangle's
        t_lo, t_hi = t_lo_all[tri], t_hi_all[tri]
        flat = flat_all[tri]
        safe = safe_all[tri]
        c0 = c0_all[tri]
        np_, nq = np_all[tri], nq_all[tri]
        pa, qb = np_ * a, nq * b
        c00 = (c0 - pa - qb) / safe
        c01 = (c0 - pa - (qb + nq)) / safe
        c10 = (c0 - (pa + np_) - qb) / safe
        c11 = (c0 - (pa + np_) - (qb + nq)) / safe
        c_lo = np.minimum(np.minimum(c00, c01), np.minimum(c10, c11))
        c_hi = np.maximum(np.maximum(c00, c01), np.maximum(c10, c11))
        eps = eps_all[tri]
        w_lo = np.where(flat, np.maximum(t_lo, c_lo - eps), t_lo)
        w_hi = np.where(flat, np.minimum(t_hi, c_hi + eps), t_hi)
        inside &= flat
        level = level_all[tri]
        k0 = np.maximum(np.floor(w_lo).astype(np.int64), lo_d[tri])
        k1 = np.minimum(np.floor(w_hi).astype(np.int64), hi_d[tri])
        nk = np.maximum(k1 - k0 + 1, 0)
        # expand each column into its voxels (in chunks: a steep column can hold many)
        for cs in _batches(nk):
            kk = nk[cs]
            total = int(kk.sum())
            if not total:
                continue
            if total == len(cs) and bool((kk == 1).all()):  # one voxel a column (faces across their axis)
                col = cs
                k = k0[cs]
            else:
                col = np.repeat(cs, kk)
                k = k0[col] + np.arange(total) - np.repeat(np.cumsum(kk) - kk, kk)
            t = tri[col]
            ijk = np.empty((total, 3), dtype=np.int64)
            dc, pc, ac, bc = dt[col], pt[col], a[col], b[col]
            for axis in range(3):
                ijk[:, axis] = np.where(dc == axis, k, np.where(pc == axis, ac, bc))
            # sure: the voxel's extent along d, [lo_d, hi_d) (cut by the band along z), meets the
            # plane's range over the square: (c_lo, c_hi) beyond rounding, or exactly the level
            sure = inside[col]
            if sure.any():
                kf = k.astype(np.float64)
                zd = dc == 2
                box_lo = np.where(zd, np.maximum(kf, w_band[0]), kf)
                box_hi = np.where(zd, np.minimum(kf + 1.0, w_band[1]), kf + 1.0)
                e = eps[col]
                lev = t_lo[col]
                sure &= np.where(
                    level[col],
                    (box_lo <= lev) & (lev < box_hi),
                    (c_lo[col] + e < box_hi) & (c_hi[col] - e > box_lo),
                )
            hint = np.where(
                sure, np.where(level[col], dc, _PLANE), np.where(level[col], _LEVEL + dc, _NO_HINT)
            )
            yield t, ijk, hint


# --- the test --------------------------------------------------------------------------------------
def _boxes(ijk: IntArray, w_band: tuple[float, float]) -> tuple[FloatArray, FloatArray]:
    lo = ijk.astype(np.float64)
    hi = lo + 1.0
    lo[:, 2] = np.maximum(lo[:, 2], w_band[0])
    hi[:, 2] = np.minimum(hi[:, 2], w_band[1])
    return lo, hi


_AXES_AT_ONCE = 4096
"""Up to this many pairs, the ten axes are tested at once; beyond, one by one (skipping what is
decided). Both compute the same numbers."""


def _ten_axes(
    e: FloatArray,
    rel: FloatArray,
    size: FloatArray,
    *,
    big_v: FloatArray,
    big_r: FloatArray,
    reach: FloatArray,
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """The ten non-box axes of triangles with edges ``e (m, 3, 3)`` against boxes ``[0, size)`` with the
    vertices at ``rel (m, 3, 3)`` from the box's corner: per pair, whether one separates them, and per
    axis whether it is within rounding of a tie (``(m, 10)``). Axis 0 is the triangle's normal,
    ``1 + 3 i + j`` edge ``i`` x unit vector ``j``."""
    m = len(e)
    ax = np.zeros((m, 10, 3))
    ax[:, 0] = _cross(e[:, 0], e[:, 1])
    for i in range(3):
        ex, ey, ez = e[:, i, 0], e[:, i, 1], e[:, i, 2]
        n = 1 + 3 * i  # edge i x unit x, y, z: (0, ez, -ey), (-ez, 0, ex), (ey, -ex, 0)
        ax[:, n, 1], ax[:, n, 2] = ez, -ey
        ax[:, n + 1, 0], ax[:, n + 1, 2] = -ez, ex
        ax[:, n + 2, 0], ax[:, n + 2, 1] = ey, -ex
    ax0, ax1, ax2 = ax[:, :, 0], ax[:, :, 1], ax[:, :, 2]
    # an axis along x, y or z (or none) is a box axis's test again, decided exactly before
    oblique = ((ax0 != 0).astype(np.int8) + (ax1 != 0) + (ax2 != 0)) >= 2
    p0, p1, p2 = (
        ax0 * rel[:, k, 0, None] + ax1 * rel[:, k, 1, None] + ax2 * rel[:, k, 2, None] for k in range(3)
    )
    tmin = np.minimum(np.minimum(p0, p1), p2)
    tmax = np.maximum(np.maximum(p0, p1), p2)
    l0, l1, l2 = ax0 * size[:, 0, None], ax1 * size[:, 1, None], ax2 * size[:, 2, None]
    bmin = np.minimum(l0, 0.0) + np.minimum(l1, 0.0) + np.minimum(l2, 0.0)
    bmax = np.maximum(l0, 0.0) + np.maximum(l1, 0.0) + np.maximum(l2, 0.0)
    size_ax = np.abs(ax0) + np.abs(ax1) + np.abs(ax2)
    bv = big_v[:, None]
    ax_err = np.repeat(bv, 10, axis=1)  # the axis's own rounding, in units of ulp
    ax_err[:, 0] = big_v * reach
    tol = TOLERANCES.voxel_tie * ((size_ax + ax_err) * big_r[:, None] + size_ax * bv)
    apart = oblique & ((tmin > bmax + tol) | (tmax < bmin - tol))
    near = oblique & ((np.abs(tmin - bmax) <= tol) | (np.abs(tmax - bmin) <= tol))
    return apart.any(axis=1), near


def _one_axis(
    n_axis: int,
    apart: npt.NDArray[np.bool_],
    near: npt.NDArray[np.bool_],
    *,
    e: FloatArray,
    rel: FloatArray,
    size: FloatArray,
    big_v: FloatArray,
    big_r: FloatArray,
    reach: FloatArray,
) -> None:
    """Axis ``n_axis`` of :func:`_ten_axes`, for the pairs not ``apart`` yet (updates ``apart`` and
    ``near[:, n_axis]``)."""
    edge = e[:, (n_axis - 1) // 3] if n_axis else e[:, 0]
    ax = np.zeros_like(edge)
    j = (n_axis - 1) % 3
    if n_axis == 0:
        ax = _cross(e[:, 0], e[:, 1])
    elif j == 0:
        ax[:, 1], ax[:, 2] = edge[:, 2], -edge[:, 1]
    elif j == 1:
        ax[:, 0], ax[:, 2] = -edge[:, 2], edge[:, 0]
    else:
        ax[:, 0], ax[:, 1] = edge[:, 1], -edge[:, 0]
    # an axis along x, y or z (or none) is a box axis's test again, decided exactly before
    oblique = ((ax[:, 0] != 0).astype(np.int8) + (ax[:, 1] != 0) + (ax[:, 2] != 0)) >= 2
    idx = np.flatnonzero(oblique & ~apart)
    if not len(idx):
        return
    ax = ax[idx]
    ax0, ax1, ax2 = ax[:, 0], ax[:, 1], ax[:, 2]
    rel_i = rel[idx]
    p0, p1, p2 = _dot(ax, rel_i[:, 0]), _dot(ax, rel_i[:, 1]), _dot(ax, rel_i[:, 2])
    tmin = np.minimum(np.minimum(p0, p1), p2)
    tmax = np.maximum(np.maximum(p0, p1), p2)
    sz = size[idx]
    l0, l1, l2 = ax0 * sz[:, 0], ax1 * sz[:, 1], ax2 * sz[:, 2]
    bmin = np.minimum(l0, 0.0) + np.minimum(l1, 0.0) + np.minimum(l2, 0.0)
    bmax = np.maximum(l0, 0.0) + np.maximum(l1, 0.0) + np.maximum(l2, 0.0)
    size_ax = np.abs(ax0) + np.abs(ax1) + np.abs(ax2)
    bv = big_v[idx]
    ax_err = bv * (reach[idx] if n_axis == 0 else 1.0)  # the axis's own rounding, in units of ulp
    tol = TOLERANCES.voxel_tie * ((size_ax + ax_err) * big_r[idx] + size_ax * bv)
    apart[idx] = (tmin > bmax + tol) | (tmax < bmin - tol)
    near[idx, n_axis] = (np.abs(tmin - bmax) <= tol) | (np.abs(tmax - bmin) <= tol)


def _overlap(
    v: FloatArray, lo: FloatArray, hi: FloatArray, shift: tuple[float, float] = (0.0, 0.0)
) -> tuple[npt.NDArray[np.bool_], IntArray, npt.NDArray[np.bool_]]:
    """The float verdict for triangles ``v (m, 3, 3)`` and half-open boxes ``[lo, hi)`` (on the
    non-box axes: ``[lo - shift[0], hi - shift[1])``, see :func:`touched_pairs`):
    ``(touch, unsure rows, near axes (len(unsure), 10))``; an unsure pair is within rounding of a tie
    on the marked (non-box) axes, and is to be decided exactly on them."""
    vmin, vmax = _min3(v), _max3(v)
    # box axes: exact comparisons (a vertex on an upper face does not enter the box)
    meets = (vmax >= lo) & (vmin < hi)
    touch = meets[:, 0] & meets[:, 1] & meets[:, 2]
    # a vertex inside the half-open box: they touch (exact comparisons again)
    inside = np.zeros(len(v), dtype=np.bool_)
    for corner in range(3):
        within = (v[:, corner] >= lo) & (v[:, corner] < hi)
        inside |= within[:, 0] & within[:, 1] & within[:, 2]
    r = np.flatnonzero(touch & ~inside)
    none = np.empty(0, dtype=np.int64)
    if not len(r):
        return touch, none, np.zeros((0, 10), dtype=np.bool_)
    v = v[r]
    s_lo, s_hi = lo[r] - shift[0], hi[r] - shift[1]
    rel = v - s_lo[:, None, :]
    size = s_hi - s_lo
    e = np.stack([v[:, 1] - v[:, 0], v[:, 2] - v[:, 1], v[:, 0] - v[:, 2]], axis=1)  # (m, 3, 3)
    # rounding bounds: |v| (vertices), |rel| (vertices from the box's corner), |e| (edges)
    big_v = 1.0 + _max3(np.maximum(np.abs(vmin[r]), np.abs(vmax[r])))
    big_r = 1.0 + _max3(np.maximum(np.abs(_min3(rel)), np.abs(_max3(rel))))
    reach = 1.0 + _max3(np.maximum(np.abs(_min3(e)), np.abs(_max3(e))))
    apart = np.zeros(len(r), dtype=np.bool_)
    near = np.zeros((len(r), 10), dtype=np.bool_)
    if len(r) <= _AXES_AT_ONCE:  # few pairs: the ten axes at once (fewer numpy calls)
        apart, near = _ten_axes(e, rel, size, big_v=big_v, big_r=big_r, reach=reach)
    else:  # many: axis by axis, each only where it is oblique, for the pairs no axis separated yet
        for n_axis in range(10):
            _one_axis(n_axis, apart, near, e=e, rel=rel, size=size, big_v=big_v, big_r=big_r, reach=reach)
    touch[r] = ~apart
    unsure = ~apart & near.any(axis=1)
    return touch, r[unsure], near[unsure]


def _shift_of(values: list[float]) -> int:
    """The power of two that makes every one of ``values`` an integer."""
    return max(x.as_integer_ratio()[1].bit_length() - 1 for x in values)


def _scaled(x: float, shift: int) -> int:
    """``x * 2**shift`` exactly (an integer when ``shift`` is at least :func:`_shift_of` ``[x]``)."""
    num, den = x.as_integer_ratio()
    return num << (shift - (den.bit_length() - 1))


class _ExactTriangle:
    """One triangle in exact integers (over a power of two shared with the band's bounds and the faces'
    shifts), with its separating axes and their projections made as they are asked for."""

    __slots__ = ("axes", "edges", "faces", "points", "shift")

    def __init__(
        self, v: list[float], band: tuple[float, float], faces: tuple[float, float] = (0.0, 0.0)
    ) -> None:
        self.shift = _shift_of([*v, *(b for b in band if np.isfinite(b)), *faces])
        self.faces = (_scaled(faces[0], self.shift), _scaled(faces[1], self.shift))
        n = [_scaled(x, self.shift) for x in v]
        self.points = [n[0:3], n[3:6], n[6:9]]
        p = self.points
        self.edges = [[p[(i + 1) % 3][c] - p[i][c] for c in range(3)] for i in range(3)]
        self.axes: dict[int, tuple[list[int], int, int, bool, bool]] = {}

    def axis(self, n_axis: int) -> tuple[list[int], int, int, bool, bool]:
        """Axis ``n_axis`` (see :func:`_ten_axes`): its components, the triangle's projection's ends, and
        whether a component is positive, negative."""
        got = self.axes.get(n_axis)
        if got is None:
            e = self.edges
            if n_axis == 0:
                x, y = e[0], e[1]
                ax = [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]
            else:
                i, j = divmod(n_axis - 1, 3)
                ed = e[i]
                ax = [[0, ed[2], -ed[1]], [-ed[2], 0, ed[0]], [ed[1], -ed[0], 0]][j]
            proj = [ax[0] * x[0] + ax[1] * x[1] + ax[2] * x[2] for x in self.points]
            got = (ax, min(proj), max(proj), any(c > 0 for c in ax), any(c < 0 for c in ax))
            self.axes[n_axis] = got
        return got

    def separates(self, lo: list[float], hi: list[float], axes: list[int]) -> bool:
        """Does one of ``axes`` separate the triangle from the half-open box ``[lo, hi)`` (its faces
        shifted: ``[lo - faces[0], hi - faces[1])``), exactly? (A tie separates when the box's end there
        moves in as its upper faces do.)"""
        b0 = [_scaled(x, self.shift) - self.faces[0] for x in lo]
        b1 = [_scaled(x, self.shift) - self.faces[1] for x in hi]
        for n_axis in axes:
            ax, tmin, tmax, positive, negative = self.axis(n_axis)
            lo_end = [b0[c] if ax[c] >= 0 else b1[c] for c in range(3)]
            hi_end = [b1[c] if ax[c] >= 0 else b0[c] for c in range(3)]
            bmin = ax[0] * lo_end[0] + ax[1] * lo_end[1] + ax[2] * lo_end[2]
            bmax = ax[0] * hi_end[0] + ax[1] * hi_end[1] + ax[2] * hi_end[2]
            if tmin > bmax or tmax < bmin:
                return True
            if tmin == bmax and positive:
                return True
            if tmax == bmin and negative:
                return True
        return False


def _exact_separated(
    cells: FloatArray,
    t: IntArray,
    lo: FloatArray,
    hi: FloatArray,
    near: npt.NDArray[np.bool_],
    *,
    band: tuple[float, float],
    shift: tuple[float, float] = (0.0, 0.0),
) -> list[bool]:
    """For each unsure pair (triangle ``t``, box ``[lo, hi)``, its near axes), whether an axis
    separates them exactly (each triangle made exact once)."""
    made: dict[int, _ExactTriangle] = {}
    out = []
    for tri, box_lo, box_hi, axes in zip(t.tolist(), lo.tolist(), hi.tolist(), near, strict=True):
        exact = made.get(tri)
        if exact is None:
            exact = made[tri] = _ExactTriangle(cells[tri].reshape(-1).tolist(), band, shift)
        out.append(exact.separates(box_lo, box_hi, np.flatnonzero(axes).tolist()))
    return out


def touched_pairs(
    cells: FloatArray,
    *,
    lo: tuple[int, int, int] | IntArray,
    hi: tuple[int, int, int] | IntArray,
    w_band: tuple[float, float],
    shift: tuple[float, float] = (0.0, 0.0),
) -> tuple[IntArray, IntArray, IntArray]:
    """Every (triangle, voxel) pair that touch: ``(triangle index (m,), voxel (m, 3) i, j, k, hint
    (m,))``; the hints make :func:`nearest_points` cheaper (see :data:`_NO_HINT`).

    Args:
        cells: ``(n, 3, 3)`` triangles in cell coordinates.
        lo, hi: the voxel index range ``[lo, hi)`` per axis (the frame; k: the band's layers).
        w_band: the band ``[w_lo, w_hi)`` in cell units of z (voxels are cut by it).
        shift: ``(down, in)``, cell units: the voxel tested is ``[lo - down, hi - in)``, its lower faces
            moved out and its upper faces moved in (see the module: ties on slanted axes). The box
            axes compare the vertices with the voxel's own faces, which gives the same verdicts only
            when no vertex coordinate lies within the shift of a grid plane (or a band's end) but on
            it, as :func:`twin.maps.grid.grid_coordinates` makes them (``TOLERANCES.grid_m``).
    """
    lo_a, hi_a = np.asarray(lo, dtype=np.int64), np.asarray(hi, dtype=np.int64)
    tris, voxels, hints = [], [], []
    slack = max(shift)
    cells = np.asarray(cells, dtype=np.float64)
    for t_all, ijk_all, hint in _candidates(cells, lo_a, hi_a, w_band, slack):
        blo, bhi = _boxes(ijk_all, w_band)
        keep = bhi[:, 2] > blo[:, 2]
        sure = (hint != _NO_HINT) & (hint < _LEVEL)
        test = np.flatnonzero(keep & ~sure)
        touch = sure & keep
        t, blo, bhi = t_all[test], blo[test], bhi[test]
        hit, unsure, near = _overlap(cells[t], blo, bhi, shift)
        if len(unsure):
            apart = _exact_separated(
                cells, t[unsure], blo[unsure], bhi[unsure], near, band=w_band, shift=shift
            )
            hit[unsure] = ~np.array(apart, dtype=np.bool_)
        touch[test] = hit
        tris.append(t_all[touch])
        voxels.append(ijk_all[touch])
        hints.append(hint[touch])
    if not tris:
        return np.empty(0, dtype=np.int64), np.empty((0, 3), dtype=np.int64), np.empty(0, dtype=np.int64)
    return np.concatenate(tris).astype(np.int64), np.concatenate(voxels), np.concatenate(hints)


def touched_voxels(
    cells: FloatArray,
    *,
    lo: tuple[int, int, int] | IntArray,
    hi: tuple[int, int, int] | IntArray,
    w_band: tuple[float, float],
    shift: tuple[float, float] = (0.0, 0.0),
) -> tuple[IntArray, IntArray]:
    """Every (triangle, voxel) pair that touch: ``(triangle index (m,), voxel (m, 3) i, j, k)`` (see
    :func:`touched_pairs`)."""
    tri, ijk, _ = touched_pairs(cells, lo=lo, hi=hi, w_band=w_band, shift=shift)
    return tri, ijk
