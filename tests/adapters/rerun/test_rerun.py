"""The Rerun recording of the twin: read back from the file, and rendered in the real viewer."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import rerun.chunk as rc

from adapters.cli.app import main
from adapters.rerun import RerunRecorder, map_at, map_history
from adapters.rerun.cut import cut
from adapters.rerun.tiles import TILE, tiles_of
from tests.twin.box_lab import element_iri, spec
from tests.twin.live_helpers import TWIN, box_turtle, observe, started
from twin.config import load_config
from twin.live.events import MapPublished, MapRemoved, MapUpdated, TwinEvent
from twin.maps.grid import GridFrame, OccupancyGrid
from twin.selection.skills import parse_skill

SCREENSHOT = Path(__file__).resolve().parents[4] / "shared" / "tools" / "rrd_screenshot.sh"


def record(path: Path) -> tuple[list[TwinEvent], int]:
    """A service run on the box lab with a recorder: a table, a door, a rejection, a removal."""
    recorder = RerunRecorder(path=path)
    service, kept = started()
    for event in kept.events:  # what start() emitted before the recorder was attached
        recorder.emit(event)
    service.sinks.append(recorder)
    observe(service, "robot1", box_turtle("urn:robot1:table", 6.6, 2.0))
    observe(service, "robot1", f"<{element_iri(spec('Door A'))}> <{TWIN}isOpen> true .".encode())
    observe(service, "robot2", b"this is not turtle")
    observe(service, "robot1", box_turtle("urn:robot1:crate", 2.0, 1.0))
    observe(service, "robot1", f"<urn:robot1:table> <{TWIN}removed> true .".encode())
    recorder.close()
    return kept.events, len(service.element_shapes())


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, exited but not reaped, counts as gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ", 1)[1][0] != "Z"
    except (OSError, IndexError):
        return False


def chunks_by_entity(path: Path) -> dict[str, list]:  # type: ignore[type-arg]
    out: dict[str, list] = {}  # type: ignore[type-arg]
    with warnings.catch_warnings():  # the recorder writes no footer
        warnings.simplefilter("ignore")
        reader = rc.RrdReader(str(path))
    for chunk in reader.stream().to_chunks():
        out.setdefault(str(chunk.entity_path), []).append(chunk.to_record_batch())
    return out


def column(batch: object, name: str) -> list:  # type: ignore[type-arg]
    b = batch  # a pyarrow RecordBatch
    return b.column(b.schema.get_field_index(name)).to_pylist()  # type: ignore[attr-defined]


def served_versions(events: list[TwinEvent]) -> dict[tuple[str, str], dict[int, np.ndarray]]:
    """Every map as the daemon served it after each revision: full maps, then updates applied."""
    out: dict[tuple[str, str], dict[int, np.ndarray]] = {}
    current: dict[tuple[str, str], np.ndarray] = {}
    for e in events:
        if isinstance(e, MapPublished):
            key = (e.grid.storey, e.grid.skill)
            current[key] = e.grid.data.copy()
            out.setdefault(key, {})[e.revision] = current[key].copy()
        elif isinstance(e, MapUpdated):
            key = (e.storey, e.skill)
            w = e.window
            current[key][w.row0 : w.row1, w.col0 : w.col1] = e.data
            out[key][e.revision] = current[key].copy()
    return out


def test_every_map_version_reads_back_cell_for_cell_at_its_revision(tmp_path: Path) -> None:
    path = tmp_path / "twin.rrd"
    events, _ = record(path)
    served = served_versions(events)
    assert any(len(v) > 2 for v in served.values())  # some maps changed more than once
    last_revision = max(r for v in served.values() for r in v)
    for (storey, skill), versions in served.items():
        history = map_history(path, storey, skill)
        assert history, (storey, skill)
        for revision in range(last_revision + 1):
            expected = [v for r, v in sorted(versions.items()) if r <= revision]
            got = map_at(history, revision)
            if not expected:
                assert got is None
                continue
            assert got is not None, (storey, skill, revision)
            np.testing.assert_array_equal(got, expected[-1], err_msg=f"{storey}/{skill} at {revision}")


def test_a_change_logs_only_the_tiles_it_touches(tmp_path: Path) -> None:
    path = tmp_path / "twin.rrd"
    events, _ = record(path)
    entities = chunks_by_entity(path)
    tiles = {e: bs for e, bs in entities.items() if "/tiles/" in e}
    logs = {
        e: sum(len(column(b, "GridMap:data")) for b in bs if "revision" in b.schema.names)
        for e, bs in tiles.items()
    }
    placements = [b for bs in tiles.values() for b in bs if "revision" not in b.schema.names]
    updates = [e for e in events if isinstance(e, MapUpdated)]
    touched = sum(len(tiles_of(u.window)) for u in updates)
    published = {(e.grid.storey, e.grid.skill): e.grid for e in events if isinstance(e, MapPublished)}
    initial = sum(len(tiles_of(g.frame.full)) for g in published.values())
    assert sum(logs.values()) == initial + touched  # the first version whole, then only changed tiles
    # each tile's placement once, static; the revisions carry only the cells
    assert sum(b.num_rows for b in placements) == initial
    assert all(b.schema.names.count("GridMap:translation") == 0 for bs in tiles.values() for b in bs
               if "revision" in b.schema.names)  # fmt: skip


def test_observations_rejections_and_the_building_are_recorded(tmp_path: Path) -> None:
    path = tmp_path / "twin.rrd"
    _, elements = record(path)
    entities = chunks_by_entity(path)
    texts = [t for b in entities["/events"] for row in column(b, "TextLog:text") for t in row]
    assert any("robot1: accepted at revision 1" in t for t in texts)
    assert any("robot2: observation rejected: Observation is not valid Turtle" in t for t in texts)
    assert any("door(s)" in t for t in texts)
    building = [e for e in entities if e.startswith("/world/") and not e.startswith("/world/observations")]
    meshes = [e for e in building if any("Mesh3D:vertex_positions" in b.schema.names for b in entities[e])]
    assert len(meshes) == elements - 1  # every element with geometry but the observed crate
    observed = [e for e in entities if e.startswith("/world/observations/robot1/")]
    assert any(e.endswith("table") for e in observed) and any(e.endswith("crate") for e in observed)
    crate = next(e for e in observed if e.endswith("crate"))
    batch = next(b for b in entities[crate] if "observed_by" in b.schema.names)
    assert column(batch, "observed_by")[0] == ["robot1"]  # who saw it, shown on selection
    assert column(batch, "observed_revision")[0] == [3]
    assert column(batch, "observed_at")[0][0].startswith("20")
    assert any(e.endswith("/changed") for e in entities)


def test_a_stalled_recorder_never_delays_the_service(tmp_path: Path) -> None:
    recorder = RerunRecorder(path=tmp_path / "slow.rrd", max_queue=5)
    os.kill(recorder.pid, signal.SIGSTOP)  # the recorder process stops reading its pipe
    try:
        service, kept = started()
        for event in kept.events:  # the building and every map: more than the pipe holds
            recorder.emit(event)
        service.sinks.append(recorder)
        t0 = time.perf_counter()
        for i in range(20):
            assert observe(service, "robot1", box_turtle(f"urn:r:{i}", 6.6, 2.0)).ok
        assert time.perf_counter() - t0 < 5.0
        assert recorder.dropped > 0
    finally:
        os.kill(recorder.pid, signal.SIGCONT)
        recorder.close()


def test_the_recorder_process_writes_the_file_and_exits_on_close(tmp_path: Path) -> None:
    path = tmp_path / "twin.rrd"
    recorder = RerunRecorder(path=path)
    child = alive(recorder.pid)
    assert child
    recorder.close()
    assert not alive(recorder.pid) and path.exists()


@pytest.mark.skipif(not SCREENSHOT.exists(), reason=f"{SCREENSHOT} not found (../shared is absent)")
@pytest.mark.slow
def test_the_recording_renders_in_the_real_viewer_without_errors(tmp_path: Path) -> None:
    path = tmp_path / "twin.rrd"
    record(path)
    png = tmp_path / "twin.png"
    env = {**os.environ, "RR_STRICT": "1", "RR_TIMEOUT": "240", "RR_SIZE": "1200x800"}
    command = ["bash", str(SCREENSHOT), str(path), str(png)]
    r = subprocess.run(command, capture_output=True, text=True, env=env, timeout=400, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads(Path(str(png) + ".json").read_text())
    assert png.stat().st_size > 10_000
    assert not report.get("errors") and not report.get("viewer_errors"), report


def test_maps_lie_on_their_world_cells_row_zero_at_the_lowest_y(tmp_path: Path) -> None:
    path = tmp_path / "twin.rrd"
    events, _ = record(path)
    first = next(e for e in events if isinstance(e, MapPublished))
    f = first.grid.frame
    batches = chunks_by_entity(path)[f"/maps/{first.grid.storey}/{first.grid.skill}/tiles/r0_c0"]
    batch = next(b for b in batches if "revision" not in b.schema.names)  # the static placement
    h = min(TILE, f.height)
    # Checked in the real viewer: without the half turn about x the map is mirrored in y.
    assert column(batch, "GridMap:translation")[0][0] == pytest.approx(
        [f.origin_x, f.origin_y + h * f.resolution_m, first.grid.elevation_m], abs=1e-4
    )
    assert column(batch, "GridMap:rotation_axis_angle")[0][0]["angle"] == pytest.approx(np.pi)


def test_rotated_files_each_replay_alone_with_the_building_and_every_map(tmp_path: Path) -> None:
    path = tmp_path / "day.rrd"
    recorder = RerunRecorder(path=path)
    service, kept = started()
    for event in kept.events:
        recorder.emit(event)
    recorder.wait_idle()
    recorder.max_bytes = 1  # from now on, a new file before every event
    service.sinks.append(recorder)
    for i in range(3):
        observe(service, "robot1", box_turtle(f"urn:robot1:t{i}", 6.6 - i, 2.0))
    recorder.close()
    files = recorder.files
    assert len(files) >= 3 and files[0] == path and all(f.exists() for f in files)
    assert files[1].name == "day-0001.rrd"
    served = served_versions(kept.events)
    last = files[-1]
    entities = chunks_by_entity(last)
    assert any("Mesh3D:vertex_positions" in b.schema.names for e, bs in entities.items() for b in bs
               if e.startswith("/world/ground-floor/"))  # fmt: skip
    assert any(e.startswith("/world/observations/robot1/") for e in entities)
    for f in files[1:]:  # each file alone: every map whole from its first revision on, then each change
        for (storey, skill), versions in served.items():
            history = map_history(f, storey, skill)
            assert history, (f.name, storey, skill)
            for revision, cells in history:
                expected = versions[max(r for r in versions if r <= revision)]
                np.testing.assert_array_equal(
                    cells, expected, err_msg=f"{f.name} {storey}/{skill} @{revision}"
                )


def test_a_map_that_comes_back_with_another_frame_reads_back_exact_before_and_after(tmp_path: Path) -> None:
    path = tmp_path / "frames.rrd"
    big = OccupancyGrid(GridFrame(0.0, 0.0, 0.05, 300, 200), np.zeros((200, 300), np.int8), "s", "k", 0.0)
    big.data[50:60, 250:290] = 100
    small = OccupancyGrid(GridFrame(1.0, 1.0, 0.1, 90, 140), np.full((140, 90), -1, np.int8), "s", "k", 0.0)
    small.data[130:, :] = 100
    moved = OccupancyGrid(GridFrame(2.0, 1.0, 0.1, 90, 140), small.data.copy(), "s", "k", 0.0)
    recorder = RerunRecorder(path=path)
    recorder.emit(MapPublished(big, 1, 1, 1))
    recorder.emit(MapRemoved("s", "k", 2, 2))
    recorder.emit(MapPublished(small, 3, 1, 3))  # back, with another extent and resolution
    recorder.emit(MapPublished(moved, 4, 2, 4))  # and another origin, without a removal
    recorder.close()
    history = dict(map_history(path, "s", "k"))
    np.testing.assert_array_equal(history[1], big.data)
    np.testing.assert_array_equal(history[3], small.data)
    np.testing.assert_array_equal(history[4], moved.data)
    entities = chunks_by_entity(path)
    assert "/maps/s/k/tiles/r0_c0" in entities and "/maps/s/k/tiles_2/r0_c0" in entities
    placement = next(b for b in entities["/maps/s/k/tiles_1/r0_c0"] if "revision" not in b.schema.names)
    assert column(placement, "GridMap:cell_size")[0] == [pytest.approx(0.1)]  # the first placement stays


def test_a_cut_of_a_revision_range_replays_alone_from_the_state_at_its_start(tmp_path: Path) -> None:
    path = tmp_path / "day.rrd"
    events, elements = record(path)  # table at 1, door at 2, crate at 3, table removed at 4
    served = served_versions(events)
    part = tmp_path / "part.rrd"
    summary = cut([path], part, start=3, end=3)
    assert summary.state_rows > 0 and summary.range_rows > 0
    for (storey, skill), versions in served.items():
        history = map_history(part, storey, skill)
        assert history[0][0] == 2, (storey, skill)  # the maps as they were when the range starts
        for revision, cells in history:
            assert revision in (2, 3)
            expected = versions[max(r for r in versions if r <= revision)]
            np.testing.assert_array_equal(cells, expected, err_msg=f"{storey}/{skill} @{revision}")
    entities = chunks_by_entity(part)
    texts = [t for b in entities["/events"] for row in column(b, "TextLog:text") for t in row]
    assert any("accepted at revision 3" in t for t in texts)
    assert not any("accepted at revision 1" in t or "revision 4" in t for t in texts)
    meshes = [e for e, bs in entities.items() if e.startswith("/world/") and "/observations/" not in e
              and any("Mesh3D:vertex_positions" in b.schema.names for b in bs)]  # fmt: skip
    assert len(meshes) == elements - 1  # the building
    table = next(e for e in entities if e.startswith("/world/observations/robot1/") and e.endswith("table"))
    assert not any("Clear:is_recursive" in b.schema.names for b in entities[table])  # removed after the cut
    assert any(column(b, "revision") == [2] for b in entities[table])  # standing at the start
    views = rc.RrdReader(str(part)).blueprints()  # the daemon's layout, rebuilt from the maps
    assert views, "the cut carries a blueprint"


def test_a_cut_that_ends_before_it_starts_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"ends \(2\) before it starts \(5\)"):
        cut([tmp_path / "none.rrd"], tmp_path / "out.rrd", start=5, end=2)


def test_twin_record_from_recordings_cuts_a_revision_range(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "day.rrd"
    events, _ = record(path)
    served = served_versions(events)
    part = tmp_path / "part.rrd"
    assert main(["record", str(part), "--from", str(path), "--revisions", "2:"]) == 0
    assert "the state at the start" in capsys.readouterr().out
    for (storey, skill), versions in served.items():
        history = map_history(part, storey, skill)
        assert [r for r, _ in history] == [1, *sorted(r for r in versions if r >= 2)], (storey, skill)
    assert main(["record", str(part), "--from", str(path), "--revisions", "4:2"]) != 0
    assert "ends (2) before it starts (4)" in capsys.readouterr().err


def test_twin_record_refuses_a_range_past_the_recording_and_a_range_without_recordings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "day.rrd"
    record(path)  # revisions 1 to 4
    part = tmp_path / "part.rrd"
    assert main(["record", str(part), "--from", str(path), "--revisions", "7:9"]) == 1
    err = capsys.readouterr().err
    assert f"Nothing to cut: {path} hold revisions 0 to 4, none in 7:9 (no file written)." in err
    assert not part.exists()
    assert main(["record", str(part), "--revisions", "1:2"]) == 1
    assert "cut the daemon's recordings: name them with --from FILE.rrd" in capsys.readouterr().err


def test_a_moved_element_logs_its_mesh_once_and_its_placement_at_every_move(tmp_path: Path) -> None:
    path = tmp_path / "moves.rrd"
    recorder = RerunRecorder(path=path)
    service, kept = started()
    for event in kept.events:
        recorder.emit(event)
    service.sinks.append(recorder)
    for x in (6.6, 5.6, 4.6):
        assert observe(service, "robot1", box_turtle("urn:robot1:table", x, 2.0)).ok
    recorder.close()
    table = next(bs for e, bs in chunks_by_entity(path).items() if e.endswith("robot1/urn_robot1_table"))

    def logged(name: str) -> list[object]:
        return [v for b in table if name in b.schema.names for v in column(b, name) if v is not None]

    assert len(logged("Mesh3D:vertex_positions")) == 1
    assert len(logged("Transform3D:translation")) == 3
    revisions = sorted(r[0] for r in logged("observed_revision"))  # type: ignore[index]
    assert revisions == [1, 2, 3]  # who saw it when, at every move


def test_a_points_skills_cloud_is_recorded_per_storey_in_world_coordinates_at_each_version(
    tmp_path: Path,
) -> None:
    path = tmp_path / "points.rrd"
    lidar = parse_skill(
        "lidar3d", {"kind": "points", "resolution_m": 0.25, "exclude_types": ["IfcOpeningElement"]}
    )
    cfg = dataclasses.replace(load_config(), skills={"lidar3d": lidar})
    recorder = RerunRecorder(path=path)
    service, _ = started(config=cfg)
    service.sinks.append(recorder)
    service.process()  # the first clouds
    m = service.live_maps.points.clouds[("ground-floor", "lidar3d")]
    first = m.cloud()
    recorder.close()
    batches = chunks_by_entity(path)["/points/ground-floor/lidar3d"]
    positions = [p for b in batches for p in column(b, "Points3D:positions") if p is not None]
    assert len(positions) == 1 and len(positions[0]) == len(first)
    got = np.array(positions[0], dtype=np.float32)
    np.testing.assert_array_equal(got[:, :2], first.xyz[:, :2].astype(np.float32))
    assert np.allclose(got[:, 2], first.xyz[:, 2] + first.elevation_m, atol=1e-5)


def test_a_rotated_file_starts_with_every_points_skills_current_cloud(tmp_path: Path) -> None:
    path = tmp_path / "points.rrd"
    lidar = parse_skill(
        "lidar3d", {"kind": "points", "resolution_m": 0.25, "exclude_types": ["IfcOpeningElement"]}
    )
    cfg = dataclasses.replace(load_config(), skills={"lidar3d": lidar})
    recorder = RerunRecorder(path=path)
    service, kept = started(config=cfg)
    for event in kept.events:
        recorder.emit(event)
    service.sinks.append(recorder)
    service.process()  # the first clouds, in the first file
    first = service.live_maps.points.clouds[("ground-floor", "lidar3d")].cloud()
    recorder.wait_idle()
    recorder.max_bytes = 1  # a new file before the next event
    observe(service, "robot2", b"this is not turtle")  # an event that changes no cloud
    recorder.close()
    assert len(recorder.files) == 2
    for f in recorder.files:  # each file alone holds the cloud, as the daemon served it
        batches = chunks_by_entity(f)["/points/ground-floor/lidar3d"]
        positions = [p for b in batches for p in column(b, "Points3D:positions") if p is not None]
        assert len(positions) == 1, f.name
        got = np.array(positions[0], dtype=np.float32)
        np.testing.assert_array_equal(got[:, :2], first.xyz[:, :2].astype(np.float32))
        assert np.allclose(got[:, 2], first.xyz[:, 2] + first.elevation_m, atol=1e-5)
