"""The live twin keeps a points skill's cloud per storey: a changed element replaces only the voxels it
touched before and touches now, and the cloud equals a full rebuild voxel for voxel (property test on
the box lab, as the 2D maps' tests/twin/live/test_live_maps.py)."""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import examples, imported
from tests.twin.box_lab import box_lab, element_iri, spec
from tests.twin.live.test_live_maps import steps
from tests.twin.live_helpers import TWIN, Recorder, box_turtle, observe, started
from twin.config import Config, load_config
from twin.graph.store import GraphStore
from twin.live import TwinService
from twin.live.events import PointsPublished
from twin.live.snapshots import Snapshots
from twin.maps.snapshot import read_snapshot
from twin.selection.skills import parse_skill

DOOR = element_iri(spec("Door A"))
WALL = element_iri(spec("Wall A west"))


def _config(resolution_m: float = 0.2) -> Config:
    cfg = load_config()
    lidar = parse_skill(
        "lidar3d",
        # furniture in, so that the robots' boxes are in the cloud too
        {"kind": "points", "resolution_m": resolution_m, "exclude_types": ["IfcOpeningElement"]},
    )
    return dataclasses.replace(cfg, skills={**cfg.skills, "lidar3d": lidar})


def _same_cloud(service: TwinService, other: TwinService | None = None) -> None:
    points = service.live_maps.points
    assert points.clouds, "no points map"
    for key, m in points.clouds.items():
        cloud, ref = m.cloud(), points.rebuild(m)
        np.testing.assert_array_equal(cloud.keys, ref.keys, err_msg=f"{key}: voxels vs its own rebuild")
        np.testing.assert_array_equal(cloud.xyz, ref.xyz, err_msg=f"{key}: points vs its own rebuild")
        np.testing.assert_array_equal(  # to the bit (what the files carry)
            cloud.normals.view(np.int32), ref.normals.view(np.int32), err_msg=f"{key}: normals vs its rebuild"
        )
        if other is not None:
            fresh = other.live_maps.points.clouds[key].cloud()
            np.testing.assert_array_equal(cloud.keys, fresh.keys, err_msg=f"{key}: voxels vs a restart")
            np.testing.assert_array_equal(cloud.xyz, fresh.xyz, err_msg=f"{key}: points vs a restart")
            np.testing.assert_array_equal(
                cloud.normals, fresh.normals, err_msg=f"{key}: normals vs a restart"
            )


@settings(max_examples=examples(12), deadline=None, suppress_health_check=list(HealthCheck))
@given(sequence=st.lists(steps(), min_size=1, max_size=6))
def test_incremental_clouds_equal_a_full_rebuild_voxel_for_voxel(sequence: list[bytes]) -> None:
    store = imported(box_lab())
    config = _config()
    service, _ = started(store, config)
    for payload in sequence:
        observe(service, "robot1", payload)  # some are refused (e.g. removing what is not there)
    fresh, _ = started(store, config)
    _same_cloud(service, fresh)


def test_a_door_opened_changes_the_cloud_at_the_next_version_and_only_where_the_door_was() -> None:
    service, rec = started(imported(box_lab()), _config(0.1))
    points = service.live_maps.points
    key = next(k for k in points.clouds if k[1] == "lidar3d")
    m = points.clouds[key]
    before, version = m.cloud(), m.version
    door = m.parts[DOOR].keys.copy()
    assert observe(service, "robot1", f"<{DOOR}> <{TWIN}isOpen> true .".encode()).ok
    after = m.cloud()
    assert m.version == version + 1
    assert rec.of(PointsPublished)[-1].version == m.version  # published whole at the first flush
    gone = np.setdiff1d(before.keys, after.keys)
    assert len(gone) > 0 and np.isin(gone, door).all()  # voxels only the door touched are gone
    # everywhere else the cloud is the same, point for point
    keep = ~np.isin(before.keys, door)
    rows = np.searchsorted(after.keys, before.keys[keep])
    np.testing.assert_array_equal(after.xyz[rows], before.xyz[keep])
    assert DOOR not in m.parts
    _same_cloud(service)


def test_a_wall_removed_leaves_the_cloud_without_its_voxels_and_closing_the_door_is_the_same_cloud() -> None:
    rights = frozenset({"create", "dynamic", "doors", "static"})  # removing a wall needs "static"
    service, _ = started(imported(box_lab()), dataclasses.replace(_config(0.1), default_rights=rights))
    m = next(v for k, v in service.live_maps.points.clouds.items() if k[1] == "lidar3d")
    wall = m.parts[WALL].keys.copy()
    start = m.cloud()
    assert observe(service, "robot1", f"<{DOOR}> <{TWIN}isOpen> true .".encode()).ok
    assert observe(service, "robot1", f"<{DOOR}> <{TWIN}isOpen> false .".encode()).ok
    back = m.cloud()
    np.testing.assert_array_equal(back.keys, start.keys)
    np.testing.assert_array_equal(back.xyz, start.xyz)
    assert observe(service, "robot1", f"<{WALL}> <{TWIN}removed> true .".encode()).ok
    after = m.cloud()
    assert WALL not in m.parts
    assert len(np.setdiff1d(after.keys, start.keys)) == 0
    gone = np.setdiff1d(start.keys, after.keys)
    assert len(gone) > 0 and np.isin(gone, wall).all()
    _same_cloud(service)


def test_clouds_are_published_whole_at_start_and_again_after_a_change_at_most_once_a_second() -> None:
    now = [1_000_000_000_000]
    rec = Recorder()
    service = TwinService(imported(box_lab()), _config(0.2), sinks=[rec], clock=lambda: now[0])
    service.start()
    service.process()
    first = rec.of(PointsPublished)
    assert {(e.cloud.storey, e.cloud.skill) for e in first} == {("ground-floor", "lidar3d")}
    assert first[0].version == 1 and len(first[0].cloud) > 1000
    for state in ("true", "false", "true"):  # three changes within the second: one publication after it
        assert observe(service, "robot1", f"<{DOOR}> <{TWIN}isOpen> {state} .".encode()).ok
    assert len(rec.of(PointsPublished)) == 1
    now[0] += 1_000_000_000
    service.process()
    again = rec.of(PointsPublished)[1:]
    m = service.live_maps.points.clouds[("ground-floor", "lidar3d")]
    assert [e.version for e in again] == [m.version] and m.version == 4
    np.testing.assert_array_equal(again[0].cloud.keys, m.cloud().keys)
    service.process()
    assert len(rec.of(PointsPublished)) == 2  # nothing changed since: nothing more
    (entry,) = service.status()["points"]  # type: ignore[misc]
    assert entry == {"storey": "ground-floor", "skill": "lidar3d", "version": 4, "revision": 3,
                     "points": len(m.cloud())}  # fmt: skip


def _start(store: GraphStore, path: Path, config: Config) -> TwinService:
    service = TwinService(store, config, snapshot=Snapshots(path))
    service.start()
    assert service.snapshot is not None
    service.snapshot.join()
    return service


def test_the_snapshot_holds_the_clouds_and_a_restart_replays_what_changed_since(tmp_path: Path) -> None:
    store, path, config = imported(box_lab()), tmp_path / "store.snapshot", _config()
    first = _start(store, path, config)
    assert observe(first, "robot1", box_turtle("urn:robot1:crate", 2.0, 1.0)).ok
    stop = threading.Event()
    stop.set()
    first.serve_forever(stop)  # a clean stop: the snapshot at revision 1
    header, _ = read_snapshot(path)
    assert [p["skill"] for p in header["points"]] == ["lidar3d"]
    again = _start(store, path, config)
    assert again.restored_from == 1
    key = ("ground-floor", "lidar3d")
    restored = again.live.maps.points.clouds[key]  # before the scene's triangles are computed
    np.testing.assert_array_equal(restored.cloud().keys, first.live_maps.points.clouds[key].cloud().keys)
    np.testing.assert_array_equal(restored.cloud().xyz, first.live_maps.points.clouds[key].cloud().xyz)
    np.testing.assert_array_equal(
        restored.cloud().normals, first.live_maps.points.clouds[key].cloud().normals
    )
    assert observe(again, "robot1", f"<{DOOR}> <{TWIN}isOpen> true .".encode()).ok  # then no clean stop
    third = _start(store, path, config)  # from the snapshot of revision 1, the door replayed
    assert third.restored_from == 1 and third.revision == 2
    _same_cloud(third, again)


def test_an_element_redrawn_as_it_was_leaves_the_cloud_and_its_version_as_they_were() -> None:
    service, _ = started(imported(box_lab()), _config(0.1))
    points = service.live_maps.points
    m = points.clouds[("ground-floor", "lidar3d")]
    before, version = m.cloud(), m.version
    assert points.redraw({WALL, DOOR}, {"lidar3d": {WALL: True, DOOR: True}}) == []
    assert m.version == version
    np.testing.assert_array_equal(m.cloud().xyz, before.xyz)
