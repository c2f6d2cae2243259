"""The derived-state snapshot: its file never trusted blindly, and restored maps equal a rebuild."""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import box_lab, element_iri, spec
from tests.twin.live_helpers import PREFIX, TWIN, box_turtle, observe
from twin.config import Config, load_config
from twin.errors import SnapshotError
from twin.graph.store import GraphStore
from twin.live import TwinService
from twin.live.snapshots import Snapshots, restore
from twin.live.state import ElementState, load_states
from twin.maps.scene import load_scene
from twin.maps.snapshot import read_snapshot, write_snapshot
from twin.selection.skills import parse_skill_json

# --- the file -----------------------------------------------------------------------------------------


def arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    return {
        "static": rng.random((37, 53)) < 0.3,
        "data": rng.choice(np.array([-1, 0, 100], dtype=np.int8), (37, 53)),
        "vertices": rng.random((11, 3)),
        "faces": rng.integers(0, 11, (7, 3), dtype=np.int32),
        "start": np.arange(5, dtype=np.int64),
        "empty": np.empty((0, 6), dtype=np.float32),
    }


def test_a_snapshot_file_round_trips_its_header_and_arrays_exactly(tmp_path: Path) -> None:
    path = tmp_path / "store.snapshot"
    write_snapshot(path, {"revision": 7, "names": ["a", "b"]}, arrays())
    header, got = read_snapshot(path)
    assert header["revision"] == 7 and header["names"] == ["a", "b"]
    for name, a in arrays().items():
        assert got[name].dtype == a.dtype, name
        np.testing.assert_array_equal(got[name], a, err_msg=name)
    assert [p.name for p in tmp_path.iterdir()] == ["store.snapshot"]  # no temporary file left


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda b: b[: len(b) // 2], "damaged"),
        (lambda b: b[:20], "truncated"),
        (lambda b: b[:100] + bytes([b[100] ^ 0x01]) + b[101:], "damaged"),
        (lambda b: b[:-5] + bytes([b[-5] ^ 0x80]) + b[-4:], "damaged"),
        (lambda b: b"NOTASNAP" + b[8:], "not a snapshot"),
        (lambda b: b"", "truncated"),
    ],
)
def test_a_damaged_or_truncated_snapshot_file_is_refused_naming_why(tmp_path: Path, damage, message) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "store.snapshot"
    write_snapshot(path, {"revision": 7}, arrays())
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(SnapshotError, match=message):
        read_snapshot(path)


def test_a_missing_snapshot_file_is_refused_naming_its_path(tmp_path: Path) -> None:
    with pytest.raises(SnapshotError, match=r"No snapshot at .*nothing\.snapshot"):
        read_snapshot(tmp_path / "nothing.snapshot")


def test_arrays_of_objects_are_never_written(tmp_path: Path) -> None:
    with pytest.raises(SnapshotError, match="dtype object"):
        write_snapshot(tmp_path / "x.snapshot", {}, {"bad": np.array([{"a": 1}], dtype=object)})


# --- the live twin ------------------------------------------------------------------------------------

TABLE = "urn:robot1:table-1"


def start(store: GraphStore, path: Path | None, config: Config | None = None) -> TwinService:
    service = TwinService(store, config or load_config(), snapshot=None if path is None else Snapshots(path))
    service.start()
    if service.snapshot is not None:
        service.snapshot.join()  # the background write of a rebuilt start
    return service


def assert_same_as_a_rebuild(service: TwinService) -> None:
    """Every map equals that of a service started from the store alone, and the states the store's."""
    fresh = start(service.store, None, service.config)
    assert service.revision == fresh.revision
    assert sorted(service.live_maps.skill_maps) == sorted(fresh.live_maps.skill_maps)
    for key, m in fresh.live_maps.skill_maps.items():
        np.testing.assert_array_equal(service.live_maps.skill_maps[key].data, m.data, err_msg=str(key))
        assert service.live_maps.skill_maps[key].plan.frame == m.plan.frame
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))
    assert normal(service.states) == normal(load_states(service.store))


def normal(states: dict[str, ElementState]) -> dict[str, ElementState]:
    """States with their supertypes in one order (the store's GROUP_CONCAT keeps none)."""
    return {
        i: dataclasses.replace(s, ifc_types=(s.ifc_types[0], *sorted(s.ifc_types[1:])))
        for i, s in states.items()
    }


def changes(service: TwinService) -> None:
    """A table added and moved, a crate added then removed, a door opened, an imported table moved."""
    door = element_iri(spec("Door A"))
    table = element_iri(spec("Table"))
    moved = " ".join(repr(v) for v in [1.0, 0, 0, 0.5, 0, 1.0, 0, 0.3, 0, 0, 1.0, 0, 0, 0, 0, 1.0])
    for payload in (
        box_turtle(TABLE, 6.6, 2.0),
        box_turtle("urn:robot1:crate", 2.0, 1.0),
        box_turtle(TABLE, 3.0, 2.5, yaw=0.4),
        f"<{door}> <{TWIN}isOpen> true .".encode(),
        f'<{table}> <{TWIN}placement> "{moved}"^^<{TWIN}Matrix4x4> .'.encode(),
        f"{PREFIX}<urn:robot1:crate> twin:removed true .".encode(),
    ):
        assert observe(service, "robot1", payload).ok


def stop_cleanly(service: TwinService) -> None:
    stop = threading.Event()
    stop.set()
    service.serve_forever(stop)


def test_a_restart_after_a_clean_stop_restores_every_map_from_the_snapshot(tmp_path: Path) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    assert first.restored_from is None and path.exists()  # rebuilt, then written in the background
    changes(first)
    stop_cleanly(first)
    again = start(store, path)
    assert again.restored_from == first.revision == 6
    assert {m.version for m in again.live_maps.skill_maps.values()} == {1}  # as after a rebuild
    assert_same_as_a_rebuild(again)
    changes(again)  # the restored twin keeps changing as a rebuilt one would
    assert_same_as_a_rebuild(again)


def test_a_snapshot_older_than_the_store_replays_what_changed_since(tmp_path: Path) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)  # written at revision 0; then changes, and no clean stop (kill -9)
    changes(first)
    again = start(store, path)
    assert again.restored_from == 0 and again.revision == 6
    assert_same_as_a_rebuild(again)
    stop_cleanly(again)
    third = start(store, path)
    assert third.restored_from == 6
    assert_same_as_a_rebuild(third)


def test_elements_robots_added_since_the_snapshot_are_replayed_before_the_triangles_are_built(
    tmp_path: Path,
) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    for i in range(3):
        assert observe(first, "robot1", box_turtle(f"urn:robot1:box-{i}", 2.0 + 2 * i, 2.0)).ok
    assert observe(first, "robot1", box_turtle("urn:robot1:box-0", 6.6, 2.5, yaw=0.7)).ok
    assert observe(first, "robot1", f"{PREFIX}<urn:robot1:box-1> twin:removed true .".encode()).ok
    again = start(store, path)
    assert again.restored_from == 0 and again.revision == 5
    assert_same_as_a_rebuild(again)


def test_triangles_computed_piecewise_after_a_restore_equal_those_of_a_build(tmp_path: Path) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    assert first.snapshot is not None
    restored = restore(
        path, keys=first.snapshot.keys, revision=0, skills=first.skills, margin_m=first.config.margin_m
    )
    reference = load_scene(store).elements
    area = (reference.bounds[:, 3] - reference.bounds[:, 0]) * (
        reference.bounds[:, 4] - reference.bounds[:, 1]
    )
    restored.fill_near([reference.bounds[int(np.nanargmin(area))]])
    assert 0 < restored.filled.sum() < len(reference)
    restored.complete()
    got = restored.maps.scene.elements
    for name in ("triangles", "triangle_bounds", "start", "closed", "bounds"):
        np.testing.assert_array_equal(getattr(got, name), getattr(reference, name), err_msg=name)


@pytest.mark.parametrize("damage", ["flip", "truncate"])
def test_a_corrupted_snapshot_is_detected_rebuilt_and_rewritten(
    tmp_path: Path, damage: str, caplog: pytest.LogCaptureFixture
) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    stop_cleanly(start(store, path))
    data = bytearray(path.read_bytes())
    if damage == "flip":
        data[len(data) // 3] ^= 0x10
    else:
        del data[len(data) - 1000 :]
    path.write_bytes(bytes(data))
    with caplog.at_level("INFO", logger="twin.live"):
        again = start(store, path)
    assert again.restored_from is None
    assert "Rebuilding the maps from the store" in caplog.text
    assert_same_as_a_rebuild(again)
    read_snapshot(path)  # rewritten whole


def test_a_changed_skill_profile_rebuilds_its_maps_and_keeps_the_others(tmp_path: Path) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    changes(first)
    stop_cleanly(first)
    cfg = load_config()
    taller = parse_skill_json("navigation", '{"kind": "navigation", "robot_height_m": 1.9}')
    cfg = dataclasses.replace(cfg, skills={**cfg.skills, "navigation": taller})
    again = start(store, path, cfg)
    assert again.restored_from == 6
    assert again.live_maps.skill_maps[("ground-floor", "navigation")].plan.skill == taller
    assert_same_as_a_rebuild(again)
    third = start(store, path, cfg)  # and the snapshot now holds the new profile's maps
    assert third.restored_from == 6
    assert_same_as_a_rebuild(third)


def test_a_snapshot_of_another_store_or_configuration_is_not_used(tmp_path: Path) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    stop_cleanly(start(store, path))
    cfg = dataclasses.replace(load_config(), margin_m=2.0)
    assert start(store, path, cfg).restored_from is None  # the margin moves every map's frame
    other = imported(dataclasses.replace(box_lab(), source_name="other.ifc"))
    again = start(other, path)
    assert again.restored_from is None
    assert_same_as_a_rebuild(again)


def test_a_snapshot_ahead_of_the_store_is_not_used(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    changes(first)
    stop_cleanly(first)  # at revision 6; the store is then replaced by a fresh import (revision 0)
    with caplog.at_level("INFO", logger="twin.live"):
        again = start(imported(box_lab()), path)
    assert again.restored_from is None
    assert "ahead of the store (revision 6 > 0)" in caplog.text


def test_a_snapshot_written_by_other_core_code_is_rebuilt_not_served(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    stop_cleanly(start(store, path))
    assert start(store, path).restored_from == 0  # the same code: used
    # the drawing code changed (any module of twin/ does: tests/twin/live/snapshots/test_snapshot_code_key.py)
    monkeypatch.setattr("twin.live.loading.code_digest", lambda: "drawing changed")
    again = start(store, path)
    assert again.restored_from is None
    assert_same_as_a_rebuild(again)


def test_fusions_memory_survives_a_restart_from_the_snapshot_so_misses_count_on(tmp_path: Path) -> None:
    from tests.twin.live.test_views import ROOM_B, SPOT, misses, room_b_with, view

    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    t = room_b_with(first)
    assert observe(first, "robot2", view(t + 5 * 10**8, [ROOM_B])).ok
    assert misses(first, SPOT) == 1
    kept = first.live.fusion.to_json()
    stop_cleanly(first)  # writes the snapshot, fusion's memory in it

    again = start(store, path)
    assert again.restored_from is not None
    assert again.live.fusion.to_json()["tracks"] == kept["tracks"]
    assert again.live.fusion.to_json()["clocks"] == kept["clocks"]
    assert misses(again, SPOT) == 1  # counted on from where the last run left it, not from zero
    for i in (2, 3):
        assert observe(again, "robot2", view(t + i * 5 * 10**8, [ROOM_B])).ok
    assert again.states[SPOT].removed  # three misses over 1 s, across the restart


def test_a_start_without_a_snapshot_starts_fusions_memory_from_the_graph_alone(tmp_path: Path) -> None:
    from tests.twin.live.test_views import ROOM_B, SPOT, misses, room_b_with, view

    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    t = room_b_with(first)
    assert observe(first, "robot2", view(t + 5 * 10**8, [ROOM_B])).ok
    stop_cleanly(first)
    path.unlink()
    again = start(store, path)
    assert again.restored_from is None and misses(again, SPOT) == 0
