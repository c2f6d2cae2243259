"""The ingest workers' queues (:class:`adapters.zenoh.ros_workers.WorkerPool`) with a real worker
process: messages go in batches, a burst beyond the limit is refused at once, what was taken comes
back in order and the depth falls back to zero."""

from __future__ import annotations

import os
import queue
import signal
import threading
import time

from adapters.ros.detections import DetectionSettings
from adapters.zenoh.ros_hold import SETTLE_ARRAYS
from adapters.zenoh.ros_workers import Outcome, Refused, RobotSpec, Translated, WorkerPool
from tests.adapters.ros_reports import Det, cdr_detections


def test_a_burst_beyond_the_queue_limit_is_refused_and_the_rest_come_back_in_order() -> None:
    got: list[Outcome] = []
    done = threading.Event()

    def deliver(outcomes: list[Outcome]) -> None:
        got.extend(outcomes)
        if len(got) >= 14:
            done.set()

    spec = RobotSpec("robot1", DetectionSettings(robot="robot1", classes={"table": "IfcFurniture"}), None)
    pool = WorkerPool(
        [spec], 1, deliver=deliver, replay=lambda _: [], on_restart=lambda _: None,
        fusion_terms=False, typed=True, tf_wait_s=0.0, queue_depth=16,
    )  # fmt: skip
    worker = pool.workers[0].process
    assert worker is not None and worker.pid is not None
    try:
        os.kill(worker.pid, signal.SIGSTOP)  # it takes nothing until the burst is over, however slow
        try:
            pool.feed(("storey", "robot1", "ground-floor"), robot="robot1")  # one place of the 16
            pool.feed(("elevations", {"ground-floor": 0.0}))
            accepted, refused = [], 0
            table = Det((("table", 0.9),), (1.0, 0.0, 0.4), (0.5, 0.5, 0.8), id="7")
            for k in range(40):  # one burst
                stamp = 1_700_000_000_000_000_000 + k * 10**8
                try:
                    pool.put("robot1", "detections", cdr_detections(stamp, "map", [table]), stamp)
                    accepted.append(stamp)
                except queue.Full:
                    refused += 1
        finally:
            os.kill(worker.pid, signal.SIGCONT)
        assert len(accepted) == 14 and refused == 26  # 16 with the two feeds
        assert done.wait(60)
        assert all(isinstance(o, Translated | Refused) for o in got)
        assert [o.received_ns for o in got if isinstance(o, Translated)] == accepted  # in order
        deadline = time.monotonic() + 30
        while pool.depths() != [0]:
            assert time.monotonic() < deadline
            time.sleep(0.01)
    finally:
        pool.close()


def test_the_pool_holds_steady_arrays_and_passes_a_move_at_once_with_them_and_the_rest_at_its_stop() -> None:
    got: list[Outcome] = []
    lock = threading.Condition()

    def deliver(outcomes: list[Outcome]) -> None:
        with lock:
            got.extend(outcomes)
            lock.notify_all()

    def until(n: int) -> list[int]:
        with lock:
            assert lock.wait_for(lambda: len(got) >= n, timeout=60), len(got)
            return [o.received_ns for o in got if isinstance(o, Translated)]

    spec = RobotSpec("robot1", DetectionSettings(robot="robot1", classes={"table": "IfcFurniture"}), None)
    pool = WorkerPool(
        [spec], 1, deliver=deliver, replay=lambda _: [], on_restart=lambda _: None,
        fusion_terms=False, typed=True, tf_wait_s=0.0, queue_depth=64, hold_steady_s=30.0,
    )  # fmt: skip
    sent: list[int] = []

    def send(x: float) -> None:
        stamp = 1_700_000_000_000_000_000 + len(sent) * 10**8
        table = Det((("table", 0.9),), (x, 0.0, 0.4), (1.2, 0.8, 0.8), id="7")
        pool.put("robot1", "detections", cdr_detections(stamp, "map", [table]), stamp)
        sent.append(stamp)

    try:
        pool.feed(("storey", "robot1", "ground-floor"), robot="robot1")
        pool.feed(("elevations", {"ground-floor": 0.0}))
        for _ in range(1 + SETTLE_ARRAYS):  # a new track, then the arrays that settle it: at once
            send(1.0)
            assert until(len(sent)) == sent
        for _ in range(3):  # re-confirmations: held
            send(1.0)
        time.sleep(1.0)
        with lock:
            assert len(got) == 1 + SETTLE_ARRAYS
        send(2.0)  # a move: at once, after the held ones
        assert until(len(sent)) == sent
        for _ in range(SETTLE_ARRAYS):  # the sightings that complete it: at once
            send(2.0)
            assert until(len(sent)) == sent
        for _ in range(2):  # re-confirmations of the new place: held
            send(2.0)
        time.sleep(1.0)
        with lock:
            assert len(got) == len(sent) - 2
        pool.close()  # the stop passes on what is held
        assert until(len(sent)) == sent
    finally:
        pool.close()
