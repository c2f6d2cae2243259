"""Removed elements are forgotten once their tombstone outlives ``[fusion] tombstone_ttl_s``."""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from pathlib import Path

import pytest

import twin.live.service as service_module
from tests.conftest import imported
from tests.twin.box_lab import box_lab, element_iri, spec
from tests.twin.fusion.fusion_helpers import Clock, sensed
from tests.twin.live_helpers import PREFIX, TWIN, box_turtle, observe
from twin.config import load_config
from twin.graph.store import GraphStore
from twin.live import TwinService
from twin.live.census import writer_sizes
from twin.live.snapshots import Snapshots

CHAIR = "urn:robot1:chair-1"
SEEN_BY_ROBOT2 = "urn:robot2:obj-7"  # robot2's IRI for the same chair: an alias of it
HOUR_NS = 3600 * 10**9


def serving(store: GraphStore | None = None, *, clock: Clock, snapshot: Path | None = None) -> TwinService:
    service = TwinService(
        store if store is not None else imported(box_lab()),
        load_config(),
        clock=clock,
        snapshot=None if snapshot is None else Snapshots(snapshot),
    )
    service.start()
    if service.snapshot is not None:
        service.snapshot.join()
    return service


def removal(iri: str) -> bytes:
    return f"{PREFIX}<{iri}> twin:removed true .\n".encode()


def triples_of(service: TwinService, iri: str) -> int:
    rows = service.store.select(
        f"SELECT (COUNT(*) AS ?n) WHERE {{ {{ <{iri}> ?p ?o }} UNION {{ ?s ?p <{iri}> }} "
        f"UNION {{ <{iri}/geometry> ?p ?o }} }}"
    )
    return int(rows[0]["n"] or 0)


def chair_seen_then_removed(service: TwinService, clock: Clock) -> int:
    """The chair added by robot1, seen by robot2 under its own IRI (an alias), then removed; returns the
    removal's sense time."""
    assert observe(service, "robot1", box_turtle(CHAIR, 2.0, 2.0, sx=0.5, sy=0.5, sz=0.9)).ok
    clock.ns += 10**9
    seen = observe(service, "robot2", box_turtle(SEEN_BY_ROBOT2, 2.02, 2.0, sx=0.5, sy=0.5, sz=0.9))
    assert seen.body.get("resolved") == {SEEN_BY_ROBOT2: CHAIR}
    clock.ns += 10**9
    assert observe(service, "robot1", removal(CHAIR)).body["removed"] == [CHAIR]
    return clock.ns


def test_a_tombstone_is_kept_for_its_ttl_then_forgotten_from_memory_and_graph() -> None:
    clock = Clock()
    service = serving(clock=clock)
    before = writer_sizes({"live": service.live})
    triples = len(service.store)
    removed_at = chair_seen_then_removed(service, clock)

    clock.ns = removed_at + HOUR_NS - 10**9  # within the hour: kept, and a late sighting is stale
    assert service.observer.forget_tombstones() == 0
    chair = box_turtle(CHAIR, 2.0, 2.0, sx=0.5, sy=0.5, sz=0.9)
    late = observe(service, "robot1", sensed(chair, removed_at - 10**9))
    assert late.body.get("stale") == [CHAIR] and service.states[CHAIR].removed
    assert triples_of(service, CHAIR) > 10

    clock.ns = removed_at + HOUR_NS + 10**9
    assert service.observer.forget_tombstones() == 1
    assert CHAIR not in service.states and triples_of(service, CHAIR) == 0
    assert SEEN_BY_ROBOT2 not in service.live.fusion.aliases
    assert not service.store.ask(f"ASK {{ <{SEEN_BY_ROBOT2}> ?p ?o }}")
    assert len(service.store) == triples - 1 + 1  # the model's revision triple, replaced, not added
    sizes = {k: v for k, v in writer_sizes({"live": service.live}).items() if ".clocks" not in k}
    assert sizes == before | {"live.held": 1, "live.held[*]": 1}  # per robot: its clock, not per element
    assert set(service.live.held) == {service.live.site.model_iri}  # (the model's revision)
    status = service.status()
    assert status["fusion"]["forgotten"] == 1 and status["fusion"]["tombstones"] == 0  # type: ignore[index]


def test_a_report_with_a_class_after_the_ttl_creates_the_element_anew() -> None:
    clock = Clock()
    service = serving(clock=clock)
    removed_at = chair_seen_then_removed(service, clock)
    clock.ns = removed_at + HOUR_NS + 10**9
    assert service.observer.forget_tombstones() == 1
    again = observe(service, "robot1", box_turtle(CHAIR, 5.0, 1.0, sx=0.5, sy=0.5, sz=0.9))
    assert again.body["upserted"] == [CHAIR] and not service.states[CHAIR].removed
    assert service.observer.fusion_counts["created"] == 2


def test_a_restart_from_the_snapshot_taken_before_does_not_bring_a_forgotten_tombstone_back(
    tmp_path: Path,
) -> None:
    clock, store, path = Clock(), imported(box_lab()), tmp_path / "store.snapshot"
    first = serving(store, clock=clock, snapshot=path)
    removed_at = chair_seen_then_removed(first, clock)
    stop = threading.Event()
    stop.set()
    first.serve_forever(stop)  # a clean stop: the snapshot holds the tombstone
    assert CHAIR in first.live.fusion.history
    clock.ns = removed_at + HOUR_NS + 10**9
    assert first.observer.forget_tombstones() == 1  # (as a last pass before a kill -9 would)

    again = serving(store, clock=clock, snapshot=path)
    assert again.restored_from is not None
    assert CHAIR not in again.states and CHAIR not in again.live.fusion.history
    assert SEEN_BY_ROBOT2 not in again.live.fusion.aliases
    assert again.status()["fusion"]["tombstones"] == 0  # type: ignore[index]
    third = serving(store, clock=clock, snapshot=path)  # the pruned snapshot was saved again
    assert CHAIR not in third.states


def test_imported_elements_keep_their_tombstones_and_a_ttl_of_zero_keeps_every_one() -> None:
    clock = Clock()
    table = element_iri(spec("Table"))
    service = serving(clock=clock)
    assert observe(service, "robot1", removal(table)).ok
    removed_at = chair_seen_then_removed(service, clock)
    clock.ns = removed_at + 10 * HOUR_NS
    never = replace(service.config, fusion=replace(service.config.fusion, tombstone_ttl_ns=0))
    service.observer.config = never
    assert service.observer.forget_tombstones() == 0
    service.observer.config = load_config()
    assert service.observer.forget_tombstones() == 1
    assert service.states[table].removed and triples_of(service, table) > 0
    assert CHAIR not in service.states


def test_a_backlog_of_tombstones_is_forgotten_in_batches_oldest_first_skipping_those_made_again() -> None:
    clock = Clock()
    service = serving(clock=clock)
    iris = [f"urn:robot1:crate-{i}" for i in range(5)]
    for i, iri in enumerate(iris):
        assert observe(service, "robot1", box_turtle(iri, 1.0 + i, 1.0)).ok
    for iri in reversed(iris):  # removed last to first
        clock.ns += 10**9
        assert observe(service, "robot1", removal(iri)).ok
    clock.ns += HOUR_NS + 10**9
    assert service.observer.forget_tombstones(limit=2) == 2
    assert {i for i in iris if i in service.states} == set(iris[:3])  # the two removed first are gone
    assert observe(service, "robot1", box_turtle(iris[2], 3.0, 1.0)).ok  # found due, then made again
    assert service.observer.forget_tombstones(limit=2) == 2
    assert service.observer.forget_tombstones(limit=2) == 0
    assert [i for i in iris if i in service.states] == [iris[2]] and not service.states[iris[2]].removed
    assert not any(triples_of(service, i) for i in (*iris[:2], *iris[3:]))


def test_the_serving_writer_forgets_due_tombstones_in_its_housekeeping(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(service_module, "_ALIAS_CHECK_S", 0.0)  # every turn of the loop, not every 10 s
    clock = Clock()
    service = serving(clock=clock)
    removed_at = chair_seen_then_removed(service, clock)
    clock.ns = removed_at + HOUR_NS + 10**9
    stop = threading.Event()
    writer = threading.Thread(target=service.serve_forever, args=(stop,), kwargs={"poll_s": 0.01})
    writer.start()
    try:
        deadline = time.monotonic() + 10.0
        while CHAIR in service.states and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        stop.set()
        writer.join()
    assert CHAIR not in service.states and triples_of(service, CHAIR) == 0


def test_a_merged_elements_iri_stays_an_alias_of_the_element_kept_when_its_tombstone_is_forgotten() -> None:
    clock = Clock()
    service = serving(clock=clock)
    moved, kept = "urn:robot1:crate-a", "urn:robot2:crate-b"
    assert observe(service, "robot1", box_turtle(moved, 2.0, 2.0)).ok
    assert observe(service, "robot2", box_turtle(kept, 5.0, 1.0)).ok
    clock.ns += 10**9
    assert observe(service, "robot1", box_turtle(moved, 5.0, 1.0)).body.get("merged") == {moved: kept}
    clock.ns += HOUR_NS + 10**9
    assert service.observer.forget_tombstones() == 1
    assert moved not in service.states
    rows = service.store.select(f"SELECT ?p ?o WHERE {{ <{moved}> ?p ?o }}")
    assert rows == [{"p": f"{TWIN}aliasOf", "o": kept}]
    again = observe(service, "robot1", box_turtle(moved, 5.05, 1.0))
    assert again.body.get("resolved") == {moved: kept} and moved not in service.states
