"""``[robots.NAME]``: a configured robot's rights and, with a ``namespace``, the ROS 2 maps it receives.

Example::

    [robots.robot1]
    namespace = "/robot1"       # maps on /robot1/<topic> and /robot1/<topic>_updates
    storey = "ground-floor"     # the storey it starts on
    [robots.robot1.maps]        # topic under the namespace = skill (these two are the defaults)
    map = "localization"
    navigation_map = "navigation"
    [robots.robot1.full_every_s]  # for subscribers that do not apply updates (AMCL): full maps on
    map = 10.0                  # this topic at most every 10 s while its map changes
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import Field, StringConstraints, ValidationInfo, field_validator, model_validator

from twin.config.base import ConfigTable, Number, Text, Whole, list_of
from twin.config.tables import NAME_PATTERN, Right

RosLayout = Literal["bridge", "rmw_zenoh"]
RobotName = Annotated[str, StringConstraints(pattern=NAME_PATTERN)]

DEFAULT_ROBOT_MAPS: tuple[tuple[str, str], ...] = (("map", "localization"), ("navigation_map", "navigation"))
"""A namespaced robot's topics when its table names none: AMCL reads ``map`` (its default
``map_topic``), so that carries the localization skill; the costmap's static layer is pointed at
``navigation_map`` (``map_topic: navigation_map``) for the navigation skill."""
RESERVED_TOPICS = ("storey",)
"""Topic names under a robot's namespace that the daemon uses for something else (``/<ns>/storey``)."""

_NAMESPACE = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*/?$")
_TOPIC = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


@dataclass(frozen=True, slots=True)
class RobotConfig:
    """A configured robot: what it may change, and (with a ``namespace``) the ROS 2 maps it receives.

    ``maps`` pairs a topic name under the namespace with a skill, e.g. ``(("map", "localization"),
    ("navigation_map", "navigation"))``: each topic carries that skill's map of the robot's current
    ``storey`` (latched), and ``<topic>_updates`` its changed rectangles.
    """

    name: str
    rights: frozenset[Right]
    namespace: str | None = None
    maps: tuple[tuple[str, str], ...] = ()
    storey: str | None = None
    domain_id: int = 0
    ros: tuple[RosLayout, ...] = ("bridge", "rmw_zenoh")
    full_every_s: tuple[tuple[str, float], ...] = ()
    """Per topic, a full map at most every that many seconds while the topic's map changes (for
    subscribers that do not apply updates); topics not named get updates and keyframes only."""

    @property
    def skills(self) -> tuple[str, ...]:
        """The skills whose maps this robot receives, in topic order, each once."""
        return tuple(dict.fromkeys(skill for _, skill in self.maps))


class RobotTable(ConfigTable):
    """``[robots.NAME]``. Skill names are checked against the configured skills, which the loader
    passes as the validation context ``{"skills": names}``."""

    namespace: Text | None = Field(None, description='ROS namespace of its maps, e.g. "/robot1".')
    storey: Text | None = Field(None, description="The storey key it starts on (needed with a namespace).")
    maps: dict[str, Text] | None = Field(
        None, description="Topic under the namespace = skill; default: map = localization, "
        "navigation_map = navigation.",
    )  # fmt: skip
    skill: Text | None = Field(None, description='The old form of maps = { map = "SKILL" }.')
    domain_id: Annotated[Whole, Field(ge=0, le=232)] = 0
    ros: Annotated[tuple[RosLayout, ...], list_of('"bridge" and/or "rmw_zenoh"'), Field(min_length=1)] = (
        "bridge",
        "rmw_zenoh",
    )
    rights: Annotated[tuple[Right, ...], list_of("rights")] | None = Field(
        None, description="What it may do; default: [rights] default."
    )
    full_every_s: dict[str, Annotated[Number, Field(ge=0.1, le=86400.0)]] | None = Field(
        None,
        description="Topic = seconds: besides its updates, the topic's map in full at most this often "
        "while it changes, for subscribers that do not apply updates (AMCL; a static layer with "
        "subscribe_to_updates false). Default: none (updates, and the twin's keyframes).",
    )

    @field_validator("namespace")
    @classmethod
    def _namespace(cls, ns: str | None) -> str | None:
        if ns is not None and not _NAMESPACE.match(ns):
            msg = f'expected a ROS namespace such as "/robot1", got {ns!r}'
            raise ValueError(msg)
        return ns

    @field_validator("maps")
    @classmethod
    def _maps(cls, maps: dict[str, str] | None, info: ValidationInfo) -> dict[str, str] | None:
        if maps is not None:
            if not maps:
                msg = 'must map topic names to skills, e.g. { map = "localization" }, got {}'
                raise ValueError(msg)
            _check_topics(maps, info.context)
        return maps

    @field_validator("skill")
    @classmethod
    def _skill(cls, skill: str | None, info: ValidationInfo) -> str | None:
        if skill is not None:
            _check_topics({"map": skill}, info.context)
        return skill

    @model_validator(mode="after")
    def _together(self) -> RobotTable:
        if self.skill is not None and self.maps is not None:
            msg = (
                "has both 'skill' and 'maps': 'skill = \"S\"' is the old form of "
                "'maps = { map = \"S\" }'; keep only 'maps'"
            )
            raise ValueError(msg)
        if self.full_every_s:
            topics = (
                {"map"}
                if self.skill is not None
                else set(self.maps)
                if self.maps is not None
                else {t for t, _ in DEFAULT_ROBOT_MAPS}
            )
            unknown = sorted(set(self.full_every_s) - topics)
            if unknown or self.namespace is None:
                msg = (
                    f"full_every_s names {', '.join(map(repr, unknown or sorted(self.full_every_s)))}, "
                    f"not a map topic of this robot (its topics: {', '.join(sorted(topics))}"
                    f"{'' if self.namespace is not None else '; and it has no namespace'})"
                )
                raise ValueError(msg)
        if self.namespace is not None and not self.storey:
            msg = (
                "a robot with a namespace needs 'storey', the key of the storey it starts on "
                f"(got {self.storey!r})"
            )
            raise ValueError(msg)
        return self

    def record(self, name: str, default_rights: frozenset[Right]) -> RobotConfig:
        """The robot ``name`` as the daemon uses it."""
        ns = self.namespace
        if self.skill is not None:
            maps: tuple[tuple[str, str], ...] = (("map", self.skill),)
        elif self.maps is not None:
            maps = tuple(self.maps.items())
        else:
            maps = DEFAULT_ROBOT_MAPS if ns is not None else ()
        return RobotConfig(
            name=name,
            rights=frozenset(self.rights) if self.rights is not None else default_rights,
            namespace=("/" + ns.strip("/")) if ns else None,
            maps=maps,
            storey=self.storey if ns is not None else None,
            domain_id=self.domain_id,
            ros=tuple(dict.fromkeys(self.ros)),
            full_every_s=tuple(sorted((self.full_every_s or {}).items())),
        )


def _check_topics(maps: Mapping[str, str], context: Any) -> None:
    skills = context.get("skills") if isinstance(context, Mapping) else None
    for topic, skill in maps.items():
        if not _TOPIC.match(topic):
            msg = (
                f'topic {topic!r} must be a relative ROS topic name such as "map" or "nav/map" '
                "(it goes under the robot's namespace)"
            )
            raise ValueError(msg)
        if topic in RESERVED_TOPICS or topic.endswith("_updates"):
            msg = f"topic {topic!r} is taken (the daemon uses '/<ns>/storey' and '<topic>_updates' itself)"
            raise ValueError(msg)
        if skills is not None and skill not in skills:
            msg = f"topic {topic!r} names unknown skill {skill!r}; configured: {', '.join(sorted(skills))}"
            raise ValueError(msg)
