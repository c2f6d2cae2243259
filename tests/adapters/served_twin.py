"""The daemon's live path in one process, composed as ``twin serve`` composes it: a real
:class:`~twin.live.TwinService` over the box lab (two storeys), its
:class:`~adapters.zenoh.daemon.ZenohDaemon` and :class:`~adapters.zenoh.ros_maps.RosMapPublisher` on
one Zenoh peer session listening on a free loopback port (multicast scouting off), and the writer on a
thread of its own (start, then serve_forever, as the daemon's main thread runs them). Robots open client
sessions to :attr:`ServedTwin.endpoint`."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import zenoh

from adapters.ros.settings import RosSettings
from adapters.zenoh.daemon import ZenohDaemon
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.ros_maps import RosMapPublisher
from adapters.zenoh.session import session_config
from adapters.zenoh.settings import ZenohSettings
from tests.conftest import imported
from tests.integration.conftest import free_port
from tests.twin.box_lab import box_lab
from twin.config import Config, load_config
from twin.live import TwinService
from twin.live.events import TwinSink
from twin.maps.grid import GridData

KEYS = SiteKeys("twin/test")
ROBOT1 = """
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
"""


def until(predicate: Callable[[], bool], timeout_s: float = 10.0, what: str = "") -> None:
    """Wait until ``predicate()`` holds (a Zenoh sample or a writer's decision is on its way)."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what or predicate}"
        time.sleep(0.01)


def robots_config(tmp: Path, text: str = ROBOT1) -> Config:
    path = tmp / "robots.toml"
    path.write_text(text)
    return load_config(path)


@dataclass
class ServedTwin:
    endpoint: str
    session: zenoh.Session
    service: TwinService
    daemon: ZenohDaemon
    ros: RosMapPublisher
    writer: threading.Thread

    def live_map(self, storey: str, skill: str) -> GridData:
        """A copy of the cells of the writer's map (storey, skill) now (read it between requests)."""
        return self.service.live.maps.skill_maps[(storey, skill)].grid().data


@contextmanager
def served_twin(
    config: Config, *, sinks: Sequence[TwinSink] = (), followers: Sequence[TwinSink] = ()
) -> Iterator[ServedTwin]:
    """The served twin; ``sinks`` are the service's before the daemon's (as ``serve`` adds its own),
    ``followers`` the daemon's after the ROS 2 publisher."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = zenoh.open(session_config(ZenohSettings(), mode="peer", listen=[endpoint], connect=[]))
    service = TwinService(imported(box_lab(storeys=2)), config, sinks=list(sinks))
    daemon = ZenohDaemon(session, service, keys=KEYS, frame_id=config.section(RosSettings).frame_id)
    ros = RosMapPublisher.following(daemon, config)
    daemon.followers += followers
    service.sinks.append(daemon)
    stop, started = threading.Event(), threading.Event()
    failed: list[BaseException] = []

    def run() -> None:
        try:
            service.start()
        except BaseException as err:  # reported on the test's thread
            failed.append(err)
            raise
        finally:
            started.set()
        service.serve_forever(stop, poll_s=0.01)

    writer = threading.Thread(target=run, name="twin-writer", daemon=True)
    writer.start()
    try:
        assert started.wait(60) and not failed, f"the twin did not start: {failed}"
        daemon.drain()
        yield ServedTwin(endpoint, session, service, daemon, ros, writer)
    finally:
        stop.set()
        writer.join(30)
        daemon.close()
        ros.close()
        session.close()
