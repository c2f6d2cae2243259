"""Closed shells turned outward (:func:`twin.maps.meshops.orient_outward`): per shell, by its signed
volume, all meshes in one pass."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from twin.maps.meshops import orient_outward

CUBE_FACES = np.array(
    [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
     [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]],
    dtype=np.int32,
)  # fmt: skip
"""Outward, over the corners of :func:`_cube` (bottom ring, then top ring, counter-clockwise)."""


def _cube(lo: float, hi: float, x: float = 0.0, y: float = 0.0) -> npt.NDArray[np.float64]:
    ring = [(lo, lo), (hi, lo), (hi, hi), (lo, hi)]
    return np.array([(a + x, b + y, z) for z in (lo, hi) for a, b in ring], dtype=np.float64)


def _volumes(v: npt.NDArray[np.float64], f: npt.NDArray[np.int32]) -> float:
    t = v[f]
    return float((t[:, 0] * np.cross(t[:, 1], t[:, 2])).sum()) / 6


def test_an_inward_shell_nested_in_an_outward_one_is_turned_and_the_outward_one_kept() -> None:
    v = np.concatenate([_cube(0.0, 3.0), _cube(1.0, 2.0)])
    f = np.concatenate([CUBE_FACES, CUBE_FACES[:, ::-1] + 8])
    (out,) = orient_outward([(v, f)])
    assert np.array_equal(out[:12], CUBE_FACES) and np.array_equal(out[12:], CUBE_FACES + 8)
    assert _volumes(v, out) == 27.0 + 1.0


def test_shells_touching_along_an_edge_are_turned_each_on_its_own() -> None:
    a, b = _cube(0.0, 1.0), _cube(0.0, 1.0, x=1.0, y=1.0)
    v = np.concatenate([a, b])
    # b's vertical edge at its lower corner is a's at its upper corner (welded): four faces on it
    b_faces = np.where(CUBE_FACES == 0, 2 - 8, np.where(CUBE_FACES == 4, 6 - 8, CUBE_FACES)) + 8
    f = np.concatenate([CUBE_FACES[:, ::-1], b_faces]).astype(np.int32)
    (out,) = orient_outward([(v, f)])
    assert _volumes(v, out[:12]) == 1.0 and np.array_equal(out[12:], b_faces)


def test_many_meshes_are_turned_in_one_pass_and_untouched_faces_stay_the_same_array() -> None:
    ok = (_cube(0.0, 1.0), CUBE_FACES)
    inward = (_cube(5.0, 7.0), CUBE_FACES[:, ::-1].copy())
    one, two = orient_outward([ok, inward])
    assert one is CUBE_FACES
    assert _volumes(inward[0], two) == 8.0
