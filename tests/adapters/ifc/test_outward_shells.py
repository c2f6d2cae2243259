"""Closed shells are turned outward before the fill: a surface model of several closed face sets wound
either way (one set with a face flipped, one with a face holding an inner bound, a pair nested and a
pair overlapping, each pair wound oppositely) fills its navigation map like the OpenCASCADE reference
(which unites its shells), and every normal of its cloud points outward. Slow: ifcopenshell and
OpenCASCADE mesh the model."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from references.opencascade_maps import compare_model
from tests.adapters.generated import XYZ, Generated, box_faces
from tests.conftest import imported
from twin.config import Config
from twin.graph.rdf import literal_value
from twin.maps.points import build_points, plan_points
from twin.maps.scene import load_scene
from twin.records import BuildingModel
from twin.selection.skill_selection import selection_query
from twin.selection.skills import parse_skill

pytestmark = pytest.mark.slow

Box = tuple[XYZ, XYZ]
PLAIN: Box = ((0.0, 0.0, 0.0), (1.2, 1.0, 1.5))
"""Its top face has a square hole (an inner bound) closed by a pit down to z = 1.0."""
FLIPPED_FACE: Box = ((2.0, 0.0, 0.0), (3.0, 0.7, 1.2))
INWARD: Box = ((4.0, 0.0, 0.0), (4.6, 1.3, 1.0))
NESTED: tuple[Box, Box] = (((0.0, 2.0, 0.0), (2.0, 3.6, 1.4)), ((0.5, 2.4, 0.2), (1.3, 3.1, 1.0)))
OVERLAPPING: tuple[Box, Box] = (((3.0, 2.0, 0.0), (4.2, 3.0, 1.1)), ((3.7, 2.5, 0.0), (4.8, 3.5, 1.3)))
PIT = ((0.4, 0.3), (0.8, 0.7), 1.0)
BOXES = [PLAIN, FLIPPED_FACE, INWARD, *NESTED, *OVERLAPPING]


def _face(f: Any, points: dict[XYZ, Any], outer: list[XYZ], inner: list[XYZ] | None = None) -> Any:
    def loop(ring: list[XYZ]) -> Any:
        for p in ring:
            if p not in points:
                points[p] = f.createIfcCartesianPoint([float(c) for c in p])
        return f.createIfcPolyLoop([points[p] for p in ring])

    bounds = [f.createIfcFaceOuterBound(loop(outer), True)]
    if inner is not None:
        bounds.append(f.createIfcFaceBound(loop(inner), True))
    return f.createIfcFace(bounds)


def _reversed(faces: list[list[XYZ]]) -> list[list[XYZ]]:
    return [face[::-1] for face in faces]


def _with_pit(lo: XYZ, hi: XYZ) -> tuple[list[list[XYZ]], list[XYZ], list[XYZ]]:
    """The box's faces but its top, the top's outer loop and its hole (clockwise seen from above), and
    the pit below the hole (outward: into the pit's void)."""
    (x0, y0, _), (x1, y1, z1) = lo, hi
    (a0, b0), (a1, b1), zp = PIT
    faces = [face for face in box_faces(lo, hi) if {p[2] for p in face} != {z1}]
    top = [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    hole = [(a0, b0, z1), (a0, b1, z1), (a1, b1, z1), (a1, b0, z1)]
    pit = _reversed(box_faces((a0, b0, zp), (a1, b1, z1)))  # the pit's walls face into the void
    pit = [face for face in pit if {p[2] for p in face} != {z1}]  # open at the top: the hole
    return faces + pit, top, hole


def surface_model_lift(path: Path) -> Path:
    g = Generated("IFC4")
    f = g.file
    storey = g.storey("Ground", 0.0)
    g.box("IfcSlab", "Floor", (-0.5, -0.5, -0.2), (6.0, 4.5, 0.2), container=storey)
    sets = []
    points: dict[XYZ, Any] = {}
    faces, top, hole = _with_pit(*PLAIN)
    sets.append([_face(f, points, face) for face in faces] + [_face(f, points, top, hole)])
    flipped = box_faces(*FLIPPED_FACE)
    flipped[2] = flipped[2][::-1]  # one face wound against its set
    sets.append([_face(f, points, face) for face in flipped])
    sets.append([_face(f, points, face) for face in _reversed(box_faces(*INWARD))])
    for outward, inward in (NESTED, OVERLAPPING):
        sets.append([_face(f, points, face) for face in box_faces(*outward)])
        sets.append([_face(f, points, face) for face in _reversed(box_faces(*inward))])
    model = f.createIfcFaceBasedSurfaceModel([f.createIfcConnectedFaceSet(s) for s in sets])
    g.brep_element(
        "IfcFlowTerminal",
        "Lift",
        (0.0, 0.0, 0.0),
        [model],
        container=storey,
        mapped=True,
        representation_type="SurfaceModel",
    )
    return g.write(path)


def test_a_surface_model_of_shells_wound_either_way_fills_like_the_opencascade_reference(
    tmp_path: Path, read_cached: Callable[[Path], BuildingModel], config: Config
) -> None:
    path = surface_model_lift(tmp_path / "lift.ifc")
    model = read_cached(path)
    (lift,) = [e for e in model.elements if e.name == "Lift" and e.geometry is not None]
    assert lift.geometry is not None
    mesh = lift.geometry.mesh
    assert mesh.closed  # (closed meshes are filled)
    tri = mesh.vertices[mesh.faces]
    volume = float((tri[:, 0] * np.cross(tri[:, 1], tri[:, 2])).sum()) / 6
    boxes = sum(float(np.prod(np.subtract(hi, lo))) for lo, hi in BOXES)
    pit = (PIT[1][0] - PIT[0][0]) * (PIT[1][1] - PIT[0][1]) * (PLAIN[1][2] - PIT[2])
    assert volume == pytest.approx(boxes - pit)  # every shell counts positive
    store = imported(model)
    scene = load_scene(store)
    skills = [config.skill("navigation"), config.skill("localization")]
    skills = [parse_skill(s.name, {"kind": s.kind}) if s.kind == "localization" else s for s in skills]
    result = compare_model(path, store, scene, skills)
    assert (result.lost, result.invented) == ([], [])
    assert [m.describe() for m in result.maps if not m.agrees] == []
    assert sum(m.check.certain for m in result.maps) > 500


def test_every_normal_of_the_surface_models_cloud_points_outward(
    tmp_path: Path, read_cached: Callable[[Path], BuildingModel]
) -> None:
    store = imported(read_cached(surface_model_lift(tmp_path / "lift.ifc")))
    scene = load_scene(store)
    skill = parse_skill("lidar3d", {"kind": "points", "include_types": ["IfcFlowTerminal"]})
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    (storey,) = scene.storeys
    cloud = build_points(scene, plan_points(scene, skill, storey.key, iris))
    assert len(cloud) > 1000
    world = cloud.xyz + np.array([0.0, 0.0, storey.elevation_m])
    n = cloud.normals.astype(np.float64)
    outward = np.zeros(len(cloud), dtype=np.bool_)
    for lo, hi in BOXES:
        for axis in range(3):
            for end, sign in ((lo[axis], -1.0), (hi[axis], 1.0)):
                on = np.abs(world[:, axis] - end) < 1e-9
                others = [a for a in range(3) if a != axis]
                on &= (world[:, others] >= np.array(lo)[others] - 1e-9).all(axis=1)
                on &= (world[:, others] <= np.array(hi)[others] + 1e-9).all(axis=1)
                outward |= on & (n[:, axis] == sign)
    (a0, b0), (a1, b1), zp = PIT
    in_pit = (world[:, 0] >= a0 - 1e-9) & (world[:, 0] <= a1 + 1e-9)
    in_pit &= (world[:, 1] >= b0 - 1e-9) & (world[:, 1] <= b1 + 1e-9) & (world[:, 2] >= zp - 1e-9)
    centre = np.array([(a0 + a1) / 2, (b0 + b1) / 2])
    into_pit = ((centre - world[:, :2]) * n[:, :2]).sum(axis=1) > 0  # the pit's walls face its void
    outward |= in_pit & (into_pit | (n[:, 2] == 1.0) | (np.abs(world[:, 2] - PLAIN[1][2]) < 1e-9))
    assert outward.all(), world[~outward][:5].tolist()
