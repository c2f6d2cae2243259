"""``[sources.NAME]``: the building's own systems that report to the twin over ROS 2 (not robots):
Open-RMF door adapters (``rmf_door_msgs/msg/DoorState``) and obstacle detectors
(``rmf_obstacle_msgs/msg/Obstacles``). Each is an identity of its own: its observations are made
under its name, with its rights (default: doors for door states; create and dynamic for obstacles),
and the access control lets only it publish its topic.

Example::

    [sources.building-doors]
    kind = "rmf_doors"               # DoorState on /door_states
    [sources.building-doors.doors]   # RMF door_name = the twin door's IRI, GlobalId or name
    main_entrance = "2O2Fr$t4X7Zf8NOew3FLOH"

    [sources.rmf-obstacles]
    kind = "rmf_obstacles"           # Obstacles on /rmf_obstacles
    classes = { human = "IfcBuildingElementProxy" }
    levels.L1 = { storey = "ground-floor", x = 0.0, y = 0.0, yaw_deg = 0.0 }
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import Field, field_validator

from twin.config.base import ConfigTable, Flag, Number, Text, Whole, list_of
from twin.config.robots import RosLayout
from twin.config.tables import IfcClassName, Right

SourceKind = Literal["rmf_doors", "rmf_obstacles"]
DEFAULT_TOPICS: dict[str, str] = {"rmf_doors": "door_states", "rmf_obstacles": "rmf_obstacles"}
DEFAULT_SOURCE_RIGHTS: dict[str, tuple[Right, ...]] = {
    "rmf_doors": ("doors",),
    "rmf_obstacles": ("create", "dynamic"),
}
_NAMESPACE = re.compile(r"^/?([A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*/?)?$")
_TOPIC = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


@dataclass(frozen=True, slots=True)
class LevelConfig:
    """An RMF level: the storey it is, and ``twin_from_level`` (x, y in metres, yaw in radians)."""

    storey: str
    x: float = 0.0
    y: float = 0.0
    yaw_rad: float = 0.0


@dataclass(frozen=True, slots=True)
class SourceConfig:
    """A configured building system (see the module's docstring)."""

    name: str
    kind: SourceKind
    rights: frozenset[Right]
    topic: str
    namespace: str = "/"
    domain_id: int = 0
    ros: tuple[RosLayout, ...] = ("bridge", "rmw_zenoh")
    doors: tuple[tuple[str, str], ...] = ()
    classes: tuple[tuple[str, str], ...] = ()
    levels: tuple[tuple[str, LevelConfig], ...] = ()
    max_size_m: float = 20.0
    diagnostics: bool = False


class LevelTable(ConfigTable):
    storey: Text = Field(description="The twin's storey key of this RMF level.")
    x: Number = 0.0
    y: Number = 0.0
    yaw_deg: Number = 0.0


class SourceTable(ConfigTable):
    """``[sources.NAME]``."""

    kind: SourceKind = Field(description='"rmf_doors" (DoorState) or "rmf_obstacles" (Obstacles).')
    topic: Text | None = Field(None, description="Default: door_states / rmf_obstacles.")
    namespace: Text = Field("/", description='ROS namespace of the topic, e.g. "/" or "/building".')
    domain_id: Annotated[Whole, Field(ge=0, le=232)] = 0
    ros: Annotated[tuple[RosLayout, ...], list_of('"bridge" and/or "rmw_zenoh"'), Field(min_length=1)] = (
        "bridge",
        "rmw_zenoh",
    )
    rights: Annotated[tuple[Right, ...], list_of("rights")] | None = Field(
        None, description="Default: doors (rmf_doors); create, dynamic (rmf_obstacles)."
    )
    doors: dict[str, Text] = Field(
        default_factory=dict, description="RMF door_name = the twin door's IRI, GlobalId or name."
    )
    classes: dict[str, IfcClassName] = Field(
        default_factory=dict, description="RMF classification = IFC class (others are ignored)."
    )
    levels: dict[str, LevelTable] = Field(default_factory=dict, description="RMF level_name = storey.")
    max_size_m: Annotated[Number, Field(gt=0, le=1000)] = 20.0
    diagnostics: Flag = Field(
        False,
        description="Publish the ingestion's counts on <namespace>/diagnostics (DiagnosticArray, 1 Hz).",
    )

    @field_validator("namespace")
    @classmethod
    def _namespace(cls, ns: str) -> str:
        if not _NAMESPACE.match(ns):
            msg = f'expected a ROS namespace such as "/" or "/building", got {ns!r}'
            raise ValueError(msg)
        return ns

    @field_validator("topic")
    @classmethod
    def _topic(cls, topic: str | None) -> str | None:
        if topic is not None and not _TOPIC.match(topic):
            msg = f'expected a relative ROS topic name such as "door_states", got {topic!r}'
            raise ValueError(msg)
        return topic

    def record(self, name: str) -> SourceConfig:
        return SourceConfig(
            name=name,
            kind=self.kind,
            rights=frozenset(self.rights if self.rights is not None else DEFAULT_SOURCE_RIGHTS[self.kind]),
            topic=self.topic or DEFAULT_TOPICS[self.kind],
            namespace="/" + self.namespace.strip("/"),
            domain_id=self.domain_id,
            ros=tuple(dict.fromkeys(self.ros)),
            doors=tuple(self.doors.items()),
            classes=tuple(self.classes.items()),
            levels=tuple(
                (level, LevelConfig(t.storey, t.x, t.y, math.radians(t.yaw_deg)))
                for level, t in self.levels.items()
            ),
            max_size_m=self.max_size_m,
            diagnostics=self.diagnostics,
        )
