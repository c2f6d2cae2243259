"""Storey switches enter the core as requests: the writer checks them, keeps each robot's storey and
emits the event (the ROS 2 publisher republishes on it), from its own thread."""

from __future__ import annotations

import threading
from pathlib import Path

from tests.conftest import imported
from tests.twin.box_lab import box_lab
from tests.twin.live_helpers import started
from twin.config import load_config
from twin.live import Reply
from twin.live.events import RobotStoreyChanged


def ask(service, robot: str, storey: str) -> Reply:  # type: ignore[no-untyped-def]
    replies: list[Reply] = []
    service.submit_storey(robot, storey, source="zenoh", reply=replies.append)
    service.process()
    assert len(replies) == 1
    return replies[0]


def test_a_storey_switch_is_decided_by_the_writer_and_emitted_on_its_thread(tmp_path: Path) -> None:
    path = tmp_path / "robots.toml"
    path.write_text('[robots.robot1]\nnamespace = "/robot1"\nstorey = "ground-floor"\n')
    service, rec = started(imported(box_lab(storeys=2)), load_config(path))
    threads: list[str] = []
    service.sinks.append(
        type("T", (), {"emit": lambda self, e: threads.append(threading.current_thread().name)})()
    )
    assert service.robot_storey("robot1") == "ground-floor"
    unknown = ask(service, "robot9", "first-floor")
    assert not unknown.ok and "robot9" in unknown.body["error"] and "robot1" in unknown.body["error"]
    wrong = ask(service, "robot1", "attic")
    assert not wrong.ok and "attic" in wrong.body["error"] and "first-floor" in wrong.body["error"]
    assert not rec.of(RobotStoreyChanged)
    moved = ask(service, "robot1", "first-floor")
    assert moved.ok and moved.body["changed"] is True and moved.body["previous"] == "ground-floor"
    (event,) = rec.of(RobotStoreyChanged)
    assert (event.robot, event.storey, event.previous, event.source) == (
        "robot1",
        "first-floor",
        "ground-floor",
        "zenoh",
    )
    assert threads == [threading.current_thread().name]  # the writer's thread: the test's, here
    again = ask(service, "robot1", "first-floor")
    assert again.ok and again.body["changed"] is False and len(rec.of(RobotStoreyChanged)) == 1
    assert service.robot_storey("robot1") == "first-floor"
