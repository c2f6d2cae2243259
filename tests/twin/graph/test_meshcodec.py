from __future__ import annotations

import base64

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from twin.errors import ModelError
from twin.graph.meshcodec import (
    decode_mesh,
    decode_placement,
    encode_mesh,
    encode_placement,
    encode_placements,
)
from twin.maps.meshops import are_closed, is_closed, is_edge_closed, orient_faces
from twin.maps.shapes import box_mesh
from twin.records import Mesh

TETRA = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]], dtype=np.int32)


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(4, 40), st.just(3)), elements=st.floats(-1e4, 1e4)))
def test_a_mesh_round_trips_bit_for_bit(vertices: np.ndarray) -> None:
    faces = np.arange(len(vertices) - len(vertices) % 3, dtype=np.int32).reshape(-1, 3)
    mesh = Mesh(vertices, faces, False)
    again = decode_mesh(encode_mesh(mesh))
    assert again.vertices.tobytes() == vertices.tobytes()
    assert np.array_equal(again.faces, faces)
    assert again.closed is False


def test_the_closed_flag_round_trips() -> None:
    mesh = Mesh(np.eye(4, 3), TETRA, is_closed(TETRA))
    assert decode_mesh(encode_mesh(mesh)).closed is True


def test_closedness_needs_every_edge_walked_as_often_one_way_as_the_other() -> None:
    assert is_closed(TETRA)
    assert not is_closed(TETRA[:3])
    flipped = TETRA.copy()
    flipped[0] = flipped[0, ::-1]
    assert not is_closed(flipped)
    assert not is_closed(np.concatenate([TETRA, TETRA[:2]]))


def _variants() -> list[np.ndarray]:
    flipped = TETRA.copy()
    flipped[0] = flipped[0, ::-1]
    box = box_mesh(1.0, 2.0, 3.0).faces
    return [TETRA, TETRA[:3], flipped, np.concatenate([TETRA, TETRA[:2]]), box, box[1:], TETRA + 5]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(range(7)), max_size=12))
def test_many_meshes_tested_at_once_are_closed_exactly_when_each_one_is(picks: list[int]) -> None:
    variants = _variants()
    faces = [variants[i] for i in picks]
    assert are_closed(faces).tolist() == [is_closed(f) for f in faces]


def test_an_empty_mesh_among_many_is_not_closed_and_does_not_disturb_the_others() -> None:
    empty = np.zeros((0, 3), dtype=np.int32)
    assert are_closed([empty, TETRA, empty, TETRA[:3], TETRA]).tolist() == [False, True, False, False, True]
    assert are_closed([]).tolist() == []


def test_solids_touching_along_an_edge_are_closed_like_the_steps_of_a_stair() -> None:
    first = box_mesh(1.0, 1.0, 1.0)
    second = box_mesh(1.0, 1.0, 1.0)  # moved by (1, 0, 1): the two boxes share one edge
    vertices = np.concatenate([first.vertices, second.vertices + np.array([1.0, 0.0, 1.0])])
    vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[np.concatenate([first.faces, second.faces + len(first.vertices)])]
    assert len(vertices) == 14  # welded: the shared edge's two vertices are one
    assert not is_edge_closed(faces)  # that edge has four faces
    assert is_closed(faces)


def test_a_flipped_face_makes_a_mesh_edge_closed_but_not_closed_until_reoriented() -> None:
    bad = TETRA.copy()
    bad[2] = bad[2, ::-1]
    assert is_edge_closed(bad)
    assert not is_closed(bad)
    fixed = orient_faces(bad)
    assert fixed is not None
    assert is_closed(fixed)
    assert sorted(map(sorted, fixed.tolist())) == sorted(map(sorted, TETRA.tolist()))


def test_every_shell_is_oriented_on_its_own_and_open_meshes_are_not_repaired() -> None:
    two = np.concatenate([TETRA, TETRA + 4])
    two[[1, 6]] = two[[1, 6], ::-1]
    fixed = orient_faces(two)
    assert fixed is not None
    assert is_closed(fixed)
    assert orient_faces(TETRA[:3]) is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("###", "not valid base64"),
        (base64.b64encode(b"solid x").decode(), "not a PLY"),
        (encode_mesh(Mesh(np.eye(4, 3), TETRA, True))[:-8], "bytes, expected"),
    ],
)
def test_bad_mesh_literals_raise_model_error(text: str, message: str) -> None:
    with pytest.raises(ModelError, match=message):
        decode_mesh(text)


def test_placements_round_trip_and_bad_ones_are_rejected() -> None:
    m = np.eye(4)
    m[:3, 3] = [1.5, -2.25, 1e-9]
    assert np.array_equal(decode_placement(encode_placement(m)), m)
    with pytest.raises(ModelError, match="16 numbers"):
        decode_placement("1 2 3")
    bad = m.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ModelError, match="NaN"):
        encode_placement(bad)


def test_meshes_reject_nan_and_out_of_range_faces() -> None:
    with pytest.raises(ModelError, match="NaN"):
        Mesh(np.full((3, 3), np.nan), np.array([[0, 1, 2]], dtype=np.int32), False)
    with pytest.raises(ModelError, match="indices"):
        Mesh(np.zeros((3, 3)), np.array([[0, 1, 5]], dtype=np.int32), False)


def _outcome(encode: object, matrices: list[np.ndarray]) -> tuple[str, object]:
    try:
        if encode is encode_placements:
            return "texts", encode_placements(matrices)
        return "texts", [encode_placement(m) for m in matrices]
    except ModelError as err:
        return "error", str(err)


def test_placements_encoded_all_at_once_equal_them_one_by_one_errors_included() -> None:
    rng = np.random.default_rng(3)
    good = []
    for _ in range(50):
        m = np.eye(4)
        m[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        m[:3, 3] = rng.normal(size=3) * 100
        good.append(m)
    good.append(np.eye(4, dtype=np.float32))
    assert encode_placements(good) == [encode_placement(m) for m in good]
    assert encode_placements([]) == []
    nan, skewed = good[3].copy(), good[7].copy()
    nan[1, 2] = np.nan
    skewed[3, 0] = 0.5
    for bad in ([*good[:5], skewed, nan], [*good[:5], nan, skewed], [*good[:2], np.eye(3), nan]):
        one_by_one = _outcome(encode_placement, bad)
        assert one_by_one[0] == "error"
        assert _outcome(encode_placements, bad) == one_by_one
