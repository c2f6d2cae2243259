"""Meshing spreads the products over single-threaded kernel children and splits a busy child when a
core idles: every product meshed once, the same meshes however many cores it uses or splits it makes."""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import threading
import time
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

import ifcopenshell
import numpy as np
import pytest

from adapters.ifc.errors import IfcFileError
from adapters.ifc.geometry import INSTANCE_WEIGHT, MeshResult, _shards, shared_maps, start_meshing
from adapters.ifc.kernel_child import _placements, _unique_rows, placed, run_kernel
from adapters.ifc.kernel_choice import KernelChoice
from adapters.ifc.read_model import start_reading, with_geometry
from adapters.ifc.sample_lab import LabLayout
from tests.adapters.generated import Generated
from twin.errors import ModelError
from twin.records import Element, Geometry, Mesh


def test_shards_deal_every_id_exactly_once_in_near_equal_parts() -> None:
    ids = set(range(3, 1000, 7))
    shards = _shards(ids, 3)
    assert set().union(*shards) == ids
    assert sum(len(s) for s in shards) == len(ids)
    assert max(len(s) for s in shards) - min(len(s) for s in shards) <= 1


def test_shards_deal_ids_without_a_shared_map_round_robin_in_id_order() -> None:
    assert _shards(set(range(10)), 2) == [frozenset(range(0, 10, 2)), frozenset(range(1, 10, 2))]


def test_shards_leave_out_empty_parts() -> None:
    assert _shards({5}, 2) == [frozenset({5})]
    assert _shards(set(), 2) == []


def test_shards_keep_the_instances_of_a_shared_map_together_and_stay_near_equal() -> None:
    ids = set(range(100))
    together = {i: 1000 + i % 3 for i in range(0, 60, 2)}  # three maps, ten instances each
    shards = _shards(ids, 2, together)
    assert set().union(*shards) == ids and sum(len(s) for s in shards) == len(ids)
    for key in set(together.values()):
        assert sum(1 for s in shards if any(together.get(i) == key for i in s)) == 1, key

    def weight(shard: frozenset[int]) -> float:  # a body, and INSTANCE_WEIGHT for each further instance
        keys = [together[i] for i in shard if i in together]
        return len(shard) - len(keys) + sum(1 + INSTANCE_WEIGHT * (keys.count(k) - 1) for k in set(keys))

    assert abs(weight(shards[0]) - weight(shards[1])) <= 1.0
    assert len(shards[0]) != len(shards[1])  # the instances weigh less: the counts differ
    huge = {i: 7 for i in range(90)}  # one map for most products: more than a share, dealt apart
    shards = _shards(ids, 2, huge)
    assert abs(len(shards[0]) - len(shards[1])) <= 1


def test_the_products_sharing_a_representation_map_are_found_from_the_mapped_items() -> None:
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    f = g.file
    plain = g.box("IfcWall", "wall", (0.0, 0.0, 0.0), (2.0, 0.2, 2.0), container=storey)
    source = g.box("IfcFurniture", "model", (9.0, 9.0, 0.0), (0.5, 0.5, 0.5), container=storey)
    body = source.Representation.Representations[0]
    origin = f.createIfcAxis2Placement3D(f.createIfcCartesianPoint((0.0, 0.0, 0.0)), None, None)
    rmap = f.createIfcRepresentationMap(origin, body)
    chairs = []
    for i in range(3):
        chair = g.box("IfcFurniture", f"chair {i}", (float(i), 3.0, 0.0), (0.5, 0.5, 0.5), container=storey)
        target = f.createIfcCartesianTransformationOperator3D(
            None, None, f.createIfcCartesianPoint((0.0, 0.0, 0.0)), 1.0, None
        )
        rep = chair.Representation.Representations[0]
        rep.Items = [f.createIfcMappedItem(rmap, target)]
        chairs.append(chair)
    found = shared_maps(f)
    assert {pid: found.get(pid) for pid in (plain.id(), *(c.id() for c in chairs))} == {
        plain.id(): None,
        **{c.id(): rmap.id() for c in chairs},
    }
    with start_meshing(f, [plain, *chairs], kernels=("manifold",), threads=2) as job:
        meshed = job.result()
    assert set(meshed.geometry) == {plain.id(), *(c.id() for c in chairs)}


def _lab_products(lab: tuple[Path, LabLayout]) -> tuple[Any, list[Any], list[Any]]:
    f = ifcopenshell.open(str(lab[0]))
    products = [p for p in (*f.by_type("IfcElement"), *f.by_type("IfcSpace")) if p.Representation]
    router = KernelChoice()
    return f, products, [p for p in products if router.reason(p) is not None]


def _assert_same(one: MeshResult, two: MeshResult) -> None:
    assert one.unmeshed == two.unmeshed == []
    assert set(one.geometry) == set(two.geometry)
    assert one.kernel_of == two.kernel_of
    assert one.fallbacks == two.fallbacks
    for pid, g in one.geometry.items():
        h = two.geometry[pid]
        assert np.array_equal(g.mesh.vertices, h.mesh.vertices)
        assert np.array_equal(g.mesh.faces, h.mesh.faces)
        assert g.mesh.closed == h.mesh.closed
        assert np.array_equal(g.placement, h.placement)


@pytest.mark.parametrize("kernels", [("manifold",), ("manifold", "opencascade")])
def test_one_or_two_cores_give_the_same_meshes(lab: tuple[Path, LabLayout], kernels: tuple[str, ...]) -> None:
    """One kernel: one child or two; both kernels: the routed products in a child of their own."""
    f, products, routed = _lab_products(lab)
    results = []
    for threads in (1, 2):
        with start_meshing(f, products, kernels=kernels, threads=threads, routed=routed) as job:
            results.append(job.result())
    one, two = results
    assert set(one.geometry) == {p.id() for p in products}
    _assert_same(one, two)
    assert two.children >= 2


HOLD_S = 60.0
"""How long a held child waits to be asked to stop before it gives up (only when the split is broken)."""
NOT_HELD, STOPPED_WHILE_HELD, GAVE_UP = 0, 1, 2


def _held_until_stopped(held_ids: frozenset[int] | None, outcome: Any) -> Callable[..., None]:
    """:func:`run_kernel`, but the child given exactly ``held_ids`` (None: every child) waits, before it
    meshes anything, until the parent asks it to stop (its stop flag), then meshes as asked: a busy
    child however fast its products are and however loaded the machine. It sets ``outcome`` (a shared
    value) to :data:`STOPPED_WHILE_HELD`, or to :data:`GAVE_UP` if no stop came in :data:`HOLD_S`."""

    def run(f: Any, ids: list[int], kernel: str, conn: Any, stop: Any, **kwargs: Any) -> None:
        if held_ids is None or frozenset(ids) == held_ids:
            deadline = time.monotonic() + HOLD_S
            while not stop.value and time.monotonic() < deadline:
                time.sleep(0.005)
            outcome.value = STOPPED_WHILE_HELD if stop.value else GAVE_UP
        run_kernel(f, ids, kernel, conn, stop, **kwargs)

    return run


def test_a_busy_child_is_split_when_a_core_idles_and_the_meshes_are_those_of_one_child(
    lab: tuple[Path, LabLayout], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first child to finish (manifold, on the spaces alone) makes the other (OpenCASCADE, on every
    element, held until it is asked to stop) hand over what it has not meshed to two new children, and
    the meshes are those of one child."""
    f, products, _ = _lab_products(lab)
    routed = [p for p in products if p.is_a("IfcElement")]
    meshed: list[int] = []
    with start_meshing(f, products, kernels=("manifold", "opencascade"), threads=1, routed=routed) as job:
        alone = job.result()
    outcome = mp.get_context("fork").RawValue("b", NOT_HELD)
    held = _held_until_stopped(frozenset(p.id() for p in routed), outcome)
    monkeypatch.setattr("adapters.ifc.geometry.run_kernel", held)
    with start_meshing(
        f,
        products,
        kernels=("manifold", "opencascade"),
        threads=2,
        routed=routed,
        progress=lambda done, total: meshed.append(done),
    ) as job:
        split = job.result()
    assert outcome.value != NOT_HELD, "no child was given every element: none was held"
    assert outcome.value != GAVE_UP, f"the busy child was not asked to stop within {HOLD_S:.0f} s"
    assert alone.splits == 0
    # the held child meshed one product at most: what it left goes to two children
    assert split.splits >= 1 and split.children >= alone.children + 2
    assert meshed == sorted(meshed) and meshed[-1] == len(products)
    _assert_same(alone, split)


def test_each_geometry_is_handed_over_once_as_it_comes_and_is_the_models(lab: tuple[Path, LabLayout]) -> None:
    """What ``geometries()`` yields while the children mesh is what ``model()`` holds at the end."""
    with start_reading(lab[0]) as reading:
        structure = reading.structure()
        assert all(e.geometry is None for e in structure.elements)
        streamed = {guid: (geometry, kernel) for guid, geometry, kernel in reading.geometries()}
        model = reading.model()
    with_geometry = [*(e for e in model.elements if e.geometry), *(s for s in model.spaces if s.geometry)]
    assert set(streamed) == {r.guid for r in with_geometry}
    for e in model.elements:
        if e.geometry is not None:
            assert streamed[e.guid] == (e.geometry, e.mesh_kernel)  # the same objects
    for s in model.spaces:
        if s.geometry is not None:
            assert streamed[s.guid] == (s.geometry, "")


def test_rows_are_made_unique_as_numpy_does_it() -> None:
    rng = np.random.default_rng(3)
    for n in (1, 7, 300):
        rows = rng.integers(-2, 3, size=(n, 3)).astype(np.float64) / 4
        unique, first, inverse = _unique_rows(rows)
        expected = np.unique(rows, axis=0, return_index=True, return_inverse=True)
        assert np.array_equal(unique, expected[0])
        assert np.array_equal(first, expected[1])
        assert np.array_equal(inverse, expected[2].reshape(-1))


def _walls_and_round_bars() -> tuple[Any, list[Any], list[Any]]:
    """A generated storey: six box walls (manifold meshes them) and four round bars (curved profiles,
    which OpenCASCADE meshes first)."""
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    walls = [
        g.box("IfcWall", f"wall {i}", (3.0 * i, 0.0, 0.0), (2.5, 0.2, 2.5), container=storey)
        for i in range(6)
    ]
    bars = []
    for i in range(4):
        bar = g.box("IfcMember", f"bar {i}", (3.0 * i, 4.0, 0.0), (1.0, 1.0, 1.0), container=storey)
        bar.Representation.Representations[0].Items[0].SweptArea = g.file.createIfcCircleProfileDef(
            "AREA", None, None, 0.1
        )
        bars.append(bar)
    return g.file, [*walls, *bars], bars


def test_a_cancelled_job_hands_nothing_on_and_its_arrivals_end(
    lab: tuple[Path, LabLayout], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Children killed by a cancel leave nothing to a next kernel, and whoever reads the arrivals is
    told that the meshing is over."""
    f, products, _ = _lab_products(lab)
    held = _held_until_stopped(None, mp.get_context("fork").RawValue("b", NOT_HELD))
    monkeypatch.setattr("adapters.ifc.geometry.run_kernel", held)  # none ends before the cancel
    job = start_meshing(f, products, kernels=("opencascade", "manifold"), threads=2)
    job.cancel()
    ended = threading.Event()
    threading.Thread(target=lambda: (list(job.arrivals()), ended.set()), daemon=True).start()
    assert ended.wait(30), "arrivals() went on after the cancel"
    assert job.result().unmeshed  # what the killed children had not meshed is unmeshed, not retried


@pytest.mark.parametrize("threads", [1, 2])
def test_children_that_route_their_own_share_mesh_as_a_routing_made_beforehand(threads: int) -> None:
    """``route=True``: the first children name the products OpenCASCADE meshes first and leave them to
    a child of their own; every product gets the kernel and mesh it gets when the routing is given."""
    f, products, routed = _walls_and_round_bars()
    assert [p for p in products if KernelChoice().reason(p) is not None] == routed
    kernels = ("manifold", "opencascade")
    no_split = float("inf")
    with start_meshing(
        f, products, kernels=kernels, threads=threads, routed=routed, split_min_s=no_split
    ) as job:
        given = job.result()
    with start_meshing(
        f, products, kernels=kernels, threads=threads, route=True, split_min_s=no_split
    ) as job:
        by_children = job.result()
    _assert_same(given, by_children)
    assert {pid for pid, k in by_children.kernel_of.items() if k == "opencascade"} == {p.id() for p in routed}
    assert by_children.children == threads + 1  # the routing children, then one for what they routed


def test_placements_checked_together_are_those_checked_one_by_one() -> None:
    """Every matrix of a batch gets what :func:`placed` gives it alone: the placement, or its refusal."""
    rng = np.random.default_rng(7)
    cases: list[tuple[Any, float]] = []
    for _ in range(40):
        m = np.eye(4)
        m[:3, :3] = rng.normal(size=(3, 3))
        m[:3, 3] = rng.normal(size=3) * 100
        cases.append((m, float(rng.uniform(0, 50))))
    bad_row, far, nan, huge = np.eye(4), np.eye(4), np.eye(4), np.eye(4)
    bad_row[3, 0] = 0.5
    far[0, 3] = 2e8
    nan[1, 1] = np.nan
    cases += [(bad_row, 1.0), (far, 1.0), (nan, 1.0), (huge, 1e9), (np.eye(4), float("nan"))]
    rng.shuffle(cases)  # type: ignore[arg-type]
    together = list(_placements(cases))
    for (matrix, reach), (placement, refused) in zip(cases, together, strict=True):
        try:
            alone: np.ndarray | None = placed(matrix, reach)
            why = None
        except ModelError as err:
            alone, why = None, str(err)
        assert refused == why
        assert (placement is None) == (alone is None)
        if alone is not None:
            assert np.array_equal(placement, alone)
    assert sum(r is not None for _, r in together) == 5
    _, why = next(iter(_placements([(np.eye(3), 1.0)])))
    assert why == "A placement must be a 4x4 matrix, got shape (3, 3)."


def test_an_element_given_its_geometry_is_the_record_replace_makes() -> None:
    """``with_geometry`` builds the record field by field: every field must come through (a new field
    of Element fails here until with_geometry passes it on)."""
    fields = [f.name for f in dataclasses.fields(Element)]
    assert fields == [
        "guid",
        "ifc_class",
        "name",
        "materials",
        "is_static",
        "geometry",
        "ifc_types",
        "mesh_kernel",
        "facing_materials",
        "predefined_type",
        "operation_type",
    ]
    record = Element(
        guid="0abcdefghijklmnopqrstu",
        ifc_class="IfcWall",
        name="wall",
        materials=("brick", "glass"),
        is_static=True,
        ifc_types=("IfcWall", "IfcElement"),
        mesh_kernel="",
        facing_materials=("brick",),
        predefined_type="DOOR",
        operation_type="SINGLE_SWING_LEFT",
    )
    geometry = Geometry(Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]], dtype=np.int32), closed=False))
    placed_ = with_geometry(record, geometry, "manifold")
    replaced = dataclasses.replace(record, geometry=geometry, mesh_kernel="manifold")
    assert all(getattr(placed_, name) == getattr(replaced, name) for name in fields)
    assert placed_.geometry is geometry and placed_.mesh_kernel == "manifold"
    assert with_geometry(record, None, "") is record


def test_a_reading_lets_go_of_the_file_when_it_is_left_and_keeps_what_it_read(
    lab: tuple[Path, LabLayout],
) -> None:
    """Leaving the reading frees the IFC file's entities at once (while the store may still be loading),
    not whenever the caller drops the reading; the records read stay."""
    with start_reading(lab[0]) as reading:
        model = reading.model()
        file = weakref.ref(reading._f)
    assert file() is None, "the file is freed on leaving the reading"
    assert reading.model() is model and model.elements  # what was read stays
    with start_reading(lab[0]) as unread:
        pass
    with pytest.raises(IfcFileError, match="left before its model was read"):
        unread.model()
    with pytest.raises(IfcFileError, match="left before its geometries were read"):
        next(iter(unread.geometries()))
