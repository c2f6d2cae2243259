"""Helpers for the live core's tests: a started service on the box lab, observation builders."""

from __future__ import annotations

from dataclasses import dataclass, field

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab
from twin.config import Config, load_config
from twin.graph.store import GraphStore
from twin.live import Reply, TwinService
from twin.live.events import TwinEvent

TWIN = "https://w3id.org/building-twin#"
PREFIX = f"@prefix twin: <{TWIN}> .\n"


@dataclass
class Recorder:
    """A sink that keeps every event."""

    events: list[TwinEvent] = field(default_factory=list)

    def emit(self, event: TwinEvent) -> None:
        self.events.append(event)

    def of(self, kind: type) -> list:  # type: ignore[type-arg]
        return [e for e in self.events if isinstance(e, kind)]


def box_turtle(
    iri: str,
    x: float,
    y: float,
    *,
    sx: float = 0.8,
    sy: float = 0.6,
    sz: float = 0.75,
    yaw: float = 0.0,
    cls: str = "IfcFurniture",
    storey: str = "ground-floor",
) -> bytes:
    """An observation of a box standing on the storey's floor at building-lab coordinates (x, y)."""
    return (
        PREFIX + f'<{iri}> twin:ifcClass "{cls}" ; twin:storey "{storey}" ; '
        f'twin:box "{OX + x} {OY + y} {sz / 2} {sx} {sy} {sz} {yaw}" .\n'
    ).encode()


def started(store: GraphStore | None = None, config: Config | None = None) -> tuple[TwinService, Recorder]:
    rec = Recorder()
    service = TwinService(
        store if store is not None else imported(box_lab()), config or load_config(), sinks=[rec]
    )
    service.start()
    return service, rec


def observe(service: TwinService, robot: str, payload: bytes) -> Reply:
    replies: list[Reply] = []
    service.submit_observation(robot, payload, replies.append)
    service.process()
    assert len(replies) == 1
    return replies[0]
