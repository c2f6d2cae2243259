"""Meshing spreads the products over single-threaded kernel children: every product meshed once, the
same meshes however many cores it uses."""

from __future__ import annotations

from pathlib import Path

import ifcopenshell
import numpy as np
import pytest

from adapters.ifc.geometry import _shard_counts, _shards, start_meshing
from adapters.ifc.kernel_choice import KernelChoice
from adapters.ifc.sample_lab import LabLayout


@pytest.mark.parametrize(
    ("routed", "rest", "threads", "counts"),
    [
        (0, 100, 2, (0, 2)),  # one route: a child per core
        (100, 0, 2, (2, 0)),
        (10, 1000, 2, (1, 1)),  # both routes on two cores: one child each
        (500, 500, 1, (1, 1)),  # every route has a child, even on one core
        (100, 300, 4, (1, 3)),
        (0, 0, 2, (0, 0)),
    ],
)
def test_every_route_gets_a_child_and_the_cores_go_in_proportion(
    routed: int, rest: int, threads: int, counts: tuple[int, int]
) -> None:
    assert _shard_counts(routed, rest, threads) == counts


def test_shards_deal_every_id_exactly_once_in_near_equal_parts() -> None:
    ids = set(range(3, 1000, 7))
    shards = _shards(ids, 3)
    assert set().union(*shards) == ids
    assert sum(len(s) for s in shards) == len(ids)
    assert max(len(s) for s in shards) - min(len(s) for s in shards) <= 1


@pytest.mark.parametrize("kernels", [("manifold",), ("manifold", "opencascade")])
def test_one_or_two_cores_give_the_same_meshes(lab: tuple[Path, LabLayout], kernels: tuple[str, ...]) -> None:
    """One kernel: one child or two; both kernels: the routed products in a child of their own."""
    f = ifcopenshell.open(str(lab[0]))
    products = [p for p in (*f.by_type("IfcElement"), *f.by_type("IfcSpace")) if p.Representation]
    router = KernelChoice()
    routed = [p for p in products if router.reason(p) is not None]
    results = []
    for threads in (1, 2):
        with start_meshing(f, products, kernels=kernels, threads=threads, routed=routed) as job:
            results.append(job.result())
    one, two = results
    assert one.unmeshed == two.unmeshed == []
    assert set(one.geometry) == set(two.geometry) == {p.id() for p in products}
    assert one.kernel_of == two.kernel_of
    for pid, g in one.geometry.items():
        h = two.geometry[pid]
        assert np.array_equal(g.mesh.vertices, h.mesh.vertices)
        assert np.array_equal(g.mesh.faces, h.mesh.faces)
        assert g.mesh.closed == h.mesh.closed
        assert np.array_equal(g.placement, h.placement)
