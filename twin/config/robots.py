"""``[robots.NAME]``: a configured robot, as the core knows it: its name, what it may change, and the
storey it starts on.

The rest of a robot's table is its adapters': the ROS 2 keys (``namespace``, ``maps``, ``domain_id``,
``ros``, ``full_every_s``, ``detections``) are in ``adapters/ros/settings.py``, whose section the
composition root adds to every robot's table (:attr:`~twin.config.base.ConfigSection.each`).

Example::

    [robots.robot1]
    rights = ["create", "dynamic"]  # default: [rights] default
    storey = "ground-floor"         # the storey it starts on
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from pydantic import Field, StringConstraints

from twin.config.base import ConfigTable, Text, list_of
from twin.config.tables import NAME_PATTERN, Right

RobotName = Annotated[str, StringConstraints(pattern=NAME_PATTERN)]


@dataclass(frozen=True, slots=True)
class RobotConfig:
    """A configured robot: what it may change, and the storey it starts on (None: not known until it
    says)."""

    name: str
    rights: frozenset[Right]
    storey: str | None = None


class RobotTable(ConfigTable):
    """``[robots.NAME]``: a robot, what it may change and the storey it starts on; the ROS 2 adapter's
    keys (``namespace``, ``maps``, ``detections``, ...) sit beside these."""

    storey: Text | None = Field(None, description="The storey key it starts on (needed with a namespace).")
    rights: Annotated[tuple[Right, ...], list_of("rights")] | None = Field(
        None, description="What it may do; default: [rights] default."
    )

    def record(self, name: str, default_rights: frozenset[Right]) -> RobotConfig:
        """The robot ``name`` as the core uses it."""
        return RobotConfig(
            name=name,
            rights=frozenset(self.rights) if self.rights is not None else default_rights,
            storey=self.storey or None,
        )
