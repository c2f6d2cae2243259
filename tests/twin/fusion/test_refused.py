"""Fusion's memory changes only with what the store accepts: an observation the store refuses (a full
disk: a real tmpfs, mounted here as root) leaves the sightings, aliases, held moves, misses and held new
objects as they were; once the store takes writes again the same observation changes them."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import BASE
from tests.small_disk import fill_until_refused, small_tmpfs
from tests.twin.box_lab import box_lab
from tests.twin.fusion.fusion_helpers import ROOM_A, box, view, view_only
from tests.twin.live_helpers import observe, started
from twin.graph.import_model import import_model
from twin.graph.store import EmbeddedStore
from twin.live import TwinService

S = 10**9
TABLE = "urn:robot1:table"
FURNITURE = ("IfcFurniture",)


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 16 MiB tmpfs (root only: skipped otherwise)."""
    with small_tmpfs(tmp_path / "disk") as disk:
        yield disk


def fill(disk: Path, service: TwinService) -> Path:
    """Fill ``disk`` until the store refuses a write; returns the filler file (unlink it to free it)."""
    return fill_until_refused(disk, service.store)


def remembered(service: TwinService) -> dict[str, Any]:
    """Fusion's memory as its serialiser writes it, less the robots' clock offsets (a transport fact,
    counted whether or not an observation is accepted)."""
    memory = service.live.fusion.to_json()
    del memory["clocks"]
    return memory


def test_an_observation_the_full_store_refuses_leaves_fusions_memory_as_it_was(small_disk: Path) -> None:
    store = EmbeddedStore.open(small_disk / "store")
    import_model(store, box_lab(), base_iri=BASE, site="test")
    service, _ = started(store)
    t = time.time_ns()
    assert observe(service, "robot1", box(TABLE, 2.0, 2.0, sx=1.2, sy=0.8)).ok
    assert observe(service, "robot1", box(TABLE, 2.0, 2.0, sx=1.2, sy=0.8)).body["unchanged"] is True
    assert observe(service, "robot2", view_only(t, ROOM_A, detects=FURNITURE)).ok  # robot2 streams
    filler = fill(small_disk, service)
    before, revision = remembered(service), service.revision
    # the table 0.55 m on through a new IRI (an alias, a move), a new chair (held: robot2 streams), a miss
    moved = (
        box("urn:robot2:trk-1", 2.55, 2.0, sx=1.2, sy=0.8)
        + box("urn:robot2:trk-2", 1.0, 3.2, sx=0.5, sy=0.5).split(b"\n", 1)[1]
        + view(t + S // 5, ROOM_A, detects=FURNITURE)
    )
    refused = observe(service, "robot2", moved)
    assert not refused.ok and "No space left on device" in str(refused.body["error"])
    assert remembered(service) == before and service.revision == revision
    filler.unlink()
    assert service.recover_store()
    accepted = observe(service, "robot2", moved)  # the same observation, now durable
    assert accepted.ok and accepted.body["resolved"] == {"urn:robot2:trk-1": TABLE}
    after = remembered(service)
    assert after["aliases"]["urn:robot2:trk-1"][0] == TABLE and "urn:robot2:trk-2" in after["tentative"]
    assert after != before and service.revision == revision + 1
    service.store.close()
