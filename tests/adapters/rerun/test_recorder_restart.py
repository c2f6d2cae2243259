"""A recorder process that dies is replaced: the daemon side starts another after a back-off, into a
new segment that begins with every current map, and the recording goes on (a logged gap between)."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from adapters.rerun import RerunRecorder, map_at, map_history
from tests.adapters.rerun.test_rerun import alive, chunks_by_entity, column
from tests.twin.live_helpers import box_turtle, observe, started

pytestmark = pytest.mark.slow  # recorder processes, a back-off of a second


def test_a_killed_recorder_process_is_replaced_by_a_segment_that_begins_with_every_current_map(
    tmp_path: Path,
) -> None:
    path = tmp_path / "twin.rrd"
    recorder = RerunRecorder(path=path)
    service, kept = started()
    for event in kept.events:
        recorder.emit(event)
    service.sinks.append(recorder)
    observe(service, "robot1", box_turtle("urn:robot1:table", 6.6, 2.0))
    recorder.wait_idle()
    at_kill = {key: m.data.copy() for key, m in service.live_maps.skill_maps.items()}
    first = recorder.pid
    os.kill(first, signal.SIGKILL)
    deadline = time.monotonic() + 15
    while (recorder.pid == first or not alive(recorder.pid)) and time.monotonic() < deadline:
        time.sleep(0.05)  # the listener sees the end at once; the feeder waits out the 1 s back-off
    assert recorder.pid != first and alive(recorder.pid) and recorder.restarts == 1
    observe(service, "robot1", box_turtle("urn:robot1:crate", 2.0, 1.0))
    recorder.close()
    segment = tmp_path / "twin-restart1.rrd"
    assert recorder.files == [path, segment]
    for (storey, skill), cells in at_kill.items():
        history = map_history(segment, storey, skill)
        assert history, (storey, skill)  # every map, in full, from the segment's start
        np.testing.assert_array_equal(history[0][1], cells)  # as it was when the process died
        now = service.live_maps.skill_maps[(storey, skill)]
        got = map_at(history, service.revision)
        assert got is not None
        np.testing.assert_array_equal(got, now.data, err_msg=f"{storey}/{skill}")
    notes = [t for b in chunks_by_entity(segment).get("/events", []) for t in column(b, "TextLog:text")]
    assert any("recorder process died" in str(t) for t in notes), notes


def test_a_recorder_process_that_keeps_dying_is_restarted_after_a_growing_back_off(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    recorder = RerunRecorder(path=tmp_path / "twin.rrd")
    try:
        for n in (1, 2):
            pid = recorder.pid
            os.kill(pid, signal.SIGKILL)
            deadline = time.monotonic() + 15
            while recorder.restarts < n and time.monotonic() < deadline:
                time.sleep(0.05)
            assert recorder.restarts == n
    finally:
        recorder.close()
    waits = [
        r.message.split("a new one in ")[1].split(" s")[0]
        for r in caplog.records
        if "a new one in" in r.message
    ]
    assert waits == ["1", "2"]  # it died again within a minute: twice the wait
    assert recorder.files[-1].name == "twin-restart2.rrd"
