"""What counts as the same geometry: the re-confirmation tolerances applied to meshes and placements.

A robot re-reports what it sees many times a second; a report within ``TOLERANCES.same_position_m``
of every world vertex and ``same_angle_rad`` of the orientation is the same shape, so
the observation is a re-confirmation and changes nothing. Box placements are quantised far below those
tolerances before they are written (shorter literals in the store), and so are their sizes: a box that
fusion places at the sizes it reads back from a turned mesh (exact to about 1e-9 m) is the mesh it
had, so a move writes its placement alone and the sizes never drift.

Example::

    if same_shape(reported, current):
        ...  # nothing to write
"""

from __future__ import annotations

import math

import numpy as np

from twin.records import FloatArray, Mesh, Shape, to_world
from twin.tolerances import TOLERANCES


def same_mesh(a: Mesh, b: Mesh) -> bool:
    """The same mesh exactly (vertices, faces, closedness, solidity)."""
    return a is b or (
        a.closed == b.closed
        and a.solid == b.solid
        and a.vertices.shape == b.vertices.shape
        and a.faces.shape == b.faces.shape
        and bool(np.array_equal(a.faces, b.faces))
        and bool(np.array_equal(a.vertices, b.vertices))
    )


def same_shape(a: Shape, b: Shape) -> bool:
    """The same geometry within the re-confirmation tolerances: the same faces, every world vertex
    within ``TOLERANCES.same_position_m``, the orientation within
    ``same_angle_rad``."""
    (ma, pa), (mb, pb) = a, b
    if (ma.closed, ma.solid, ma.faces.shape, ma.vertices.shape) != (
        mb.closed,
        mb.solid,
        mb.faces.shape,
        mb.vertices.shape,
    ):
        return False
    if ma is not mb and not np.array_equal(ma.faces, mb.faces):
        return False
    wa = to_world(ma.vertices, pa)
    wb = to_world(mb.vertices, pb)
    if len(wa) and float(np.abs(wa - wb).max()) > TOLERANCES.same_position_m:
        return False
    # the angle of the relative rotation (orthonormal parts of the placements)
    r = _rotation(pa).T @ _rotation(pb)
    cos = (float(np.trace(r)) - 1.0) / 2.0
    return bool(np.arccos(np.clip(cos, -1.0, 1.0)) <= TOLERANCES.same_angle_rad)


def quantised_sizes(sx: float, sy: float, sz: float) -> tuple[float, float, float]:
    """A box's sizes rounded to 1 um (a size under 1 um is kept as it is, never rounded to 0)."""
    return (_micrometres(sx), _micrometres(sy), _micrometres(sz))


def _micrometres(v: float) -> float:
    q = round(v, 6)
    return q if q > 0.0 else v


def _rotation(p: FloatArray) -> FloatArray:
    m = p[:3, :3]
    scale = np.linalg.norm(m, axis=0)
    scale[scale == 0] = 1.0
    return np.asarray(m / scale)


def quantised(placement: FloatArray) -> FloatArray:
    """A box's placement rounded (rotation to 1e-9, position to 1 um): far below the re-confirmation
    tolerances, and a shorter literal in the store for every move."""
    out = np.round(placement, 9)
    out[:3, 3] = np.round(placement[:3, 3], 6)
    return np.asarray(out)


_BIG = 2.0**52  # beyond this, x * 10**k has no fraction left to round: left to numpy


def _rint_scaled(x: float, f: float) -> float | None:
    """``np.round(x, k)`` for ``f = 10.0**k``, bit for bit (numpy multiplies, rounds half to even and
    divides back; so does this, and keeps the sign of a zero); None when ``x * f`` is not finite or is
    too large for an exact ``round``."""
    y = x * f
    if not -_BIG < y < _BIG:  # also a NaN
        return None
    r = round(y)  # half to even, as rint
    return r / f if r else math.copysign(0.0, y) / f


def quantised_box_values(cx: float, cy: float, cz: float, yaw: float) -> list[float] | None:
    """``quantised(box_placement(cx, cy, cz, yaw=yaw))`` as its 16 floats, row-major, bit for bit, in
    Python floats (a dozen numpy calls on a 4x4 array cost more than the arithmetic); None when a value
    is not finite or very large (then the array path says what it does)."""
    if not math.isfinite(yaw):
        return None
    c, s = math.cos(yaw), math.sin(yaw)  # as box_placement
    q9, q6 = 1e9, 1e6
    rc, rs, rns = _rint_scaled(c, q9), _rint_scaled(s, q9), _rint_scaled(-s, q9)
    x, y, z = _rint_scaled(cx, q6), _rint_scaled(cy, q6), _rint_scaled(cz, q6)
    if rc is None or rs is None or rns is None or x is None or y is None or z is None:
        return None
    return [rc, rns, 0.0, x, rs, rc, 0.0, y, 0.0, 0.0, 1.0, z, 0.0, 0.0, 0.0, 1.0]
