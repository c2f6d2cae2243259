"""``[sources.NAME]``: the building's own systems that report to the twin (not robots): Open-RMF door
adapters and obstacle detectors, as the core knows them. Each is an identity of its own: its
observations are made under its name, with its rights (default: doors for door states; create and
dynamic for obstacles).

The rest of a source's table (its ROS 2 topic, doors, classes and levels) is the ROS adapter's
(``adapters/ros/settings.py``), whose section the composition root adds to every source's table.

Example::

    [sources.building-doors]
    kind = "rmf_doors"               # DoorState on /door_states
    rights = ["doors"]               # the default for rmf_doors
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import Field

from twin.config.base import ConfigTable, list_of
from twin.config.tables import Right

SourceKind = Literal["rmf_doors", "rmf_obstacles"]
DEFAULT_SOURCE_RIGHTS: dict[str, tuple[Right, ...]] = {
    "rmf_doors": ("doors",),
    "rmf_obstacles": ("create", "dynamic"),
}


@dataclass(frozen=True, slots=True)
class SourceConfig:
    """A configured building system: what it is and what it may change."""

    name: str
    kind: SourceKind
    rights: frozenset[Right]


class SourceTable(ConfigTable):
    """``[sources.NAME]``: a building system that reports to the twin (an Open-RMF door adapter or
    obstacle detector), what it is and what it may change; the ROS 2 adapter's keys (``topic``,
    ``doors``, ``levels``, ...) sit beside these."""

    kind: SourceKind = Field(description='"rmf_doors" (DoorState) or "rmf_obstacles" (Obstacles).')
    rights: Annotated[tuple[Right, ...], list_of("rights")] | None = Field(
        None, description="Default: doors (rmf_doors); create, dynamic (rmf_obstacles)."
    )

    def record(self, name: str) -> SourceConfig:
        return SourceConfig(
            name=name,
            kind=self.kind,
            rights=frozenset(self.rights if self.rights is not None else DEFAULT_SOURCE_RIGHTS[self.kind]),
        )
