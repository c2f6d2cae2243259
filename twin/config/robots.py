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

from twin.config.base import ConfigTable, Flag, Number, Text, Whole, list_of
from twin.config.tables import NAME_PATTERN, IfcClassName, Right

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
class DetectionConfig:
    """``[robots.NAME.detections]``: the robot's ``vision_msgs/msg/Detection3DArray`` topic and how its
    detections become observations (see ``README.md``, "ROS 2 robots report back")."""

    topic: str
    classes: tuple[tuple[str, str], ...]
    """``(class_id, IFC class)`` pairs."""
    min_score: float = 0.5
    fov_deg: float = 90.0
    range_m: float = 5.0
    rays: int = 64
    max_tilt_deg: float = 15.0
    max_detections: int = 256
    future_s: float = 2.0
    map_frame: str = "map"
    sensor_frame: str | None = None
    z_reference: Literal["storey", "building"] = "storey"
    view_skill: str | None = "localization"
    tf: str = "tf"
    tf_static: str = "tf_static"
    diagnostics: bool = False


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
    detections: DetectionConfig | None = None

    @property
    def skills(self) -> tuple[str, ...]:
        """The skills whose maps this robot receives, in topic order, each once."""
        return tuple(dict.fromkeys(skill for _, skill in self.maps))


class DetectionTable(ConfigTable):
    """``[robots.NAME.detections]``: subscribe to the robot's detections (needs its ``namespace``)."""

    topic: Text = Field(
        "detections", description='Detection3DArray topic under the namespace ("/name": absolute).'
    )
    classes: dict[str, IfcClassName] = Field(
        description='class_id -> IFC class, e.g. { table = "IfcFurniture" }; other classes are ignored.',
        min_length=1,
    )
    min_score: Annotated[Number, Field(ge=0, le=1)] = 0.5
    fov_deg: Annotated[
        Number, Field(gt=0, le=360, description="Horizontal field of view (view polygon).")
    ] = 90.0
    range_m: Annotated[Number, Field(gt=0, le=100, description="How far the detector sees, m.")] = 5.0
    rays: Annotated[
        Whole,
        Field(
            ge=8,
            le=1024,
            description="At least this many rays for the view (more to be a cell apart at full range).",
        ),
    ] = 64
    max_tilt_deg: Annotated[Number, Field(ge=0, le=90, description="Boxes tilted more are refused.")] = 15.0
    max_detections: Annotated[Whole, Field(ge=1, le=10_000)] = 256
    future_s: Annotated[Number, Field(ge=0, le=3600, description="Clock skew allowed for stamps.")] = 2.0
    map_frame: Text = Field("map", description="The robot's map frame (the twin's building XY).")
    sensor_frame: Text | None = Field(None, description="Frame of the view (default: the array's frame).")
    z_reference: Literal["storey", "building"] = Field(
        "storey", description="z = 0 of the map frame: the storey's floor, or the building's z = 0."
    )
    view_skill: Text | None = Field(
        "localization", description='Skill whose map occludes the view ("" for none).'
    )
    tf: Text = Field("tf", description='TFMessage topic under the namespace ("/tf": the global one).')
    tf_static: Text = Field("tf_static", description='Static TFMessage topic ("/tf_static": global).')
    diagnostics: Flag = Field(
        False, description="Publish the ingestion's counts on /<ns>/diagnostics (DiagnosticArray, 1 Hz)."
    )

    @field_validator("topic", "tf", "tf_static")
    @classmethod
    def _topic(cls, topic: str) -> str:
        if not _TOPIC.match(topic.removeprefix("/")):
            msg = (
                f'expected a ROS topic name such as "detections" (under the namespace) or "/tf" '
                f"(absolute), got {topic!r}"
            )
            raise ValueError(msg)
        return topic

    @field_validator("view_skill")
    @classmethod
    def _view_skill(cls, skill: str | None, info: ValidationInfo) -> str | None:
        if not skill:
            return None
        skills = info.context.get("skills") if isinstance(info.context, Mapping) else None
        if skills is not None and skill not in skills:
            msg = f"names unknown skill {skill!r}; configured: {', '.join(sorted(skills))}"
            raise ValueError(msg)
        return skill

    def record(self) -> DetectionConfig:
        return DetectionConfig(
            topic=self.topic,
            classes=tuple(self.classes.items()),
            min_score=self.min_score,
            fov_deg=self.fov_deg,
            range_m=self.range_m,
            rays=self.rays,
            max_tilt_deg=self.max_tilt_deg,
            max_detections=self.max_detections,
            future_s=self.future_s,
            map_frame=self.map_frame,
            sensor_frame=self.sensor_frame or None,
            z_reference=self.z_reference,
            view_skill=self.view_skill,
            tf=self.tf,
            tf_static=self.tf_static,
            diagnostics=self.diagnostics,
        )


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
    detections: DetectionTable | None = Field(
        None, description="Its vision_msgs/Detection3DArray topic, class table, camera and TF."
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
        if self.detections is not None and self.namespace is None:
            msg = "'detections' needs the robot's 'namespace' (its topics are under it)"
            raise ValueError(msg)
        if self.detections is not None:
            mapped = self.maps or ({"map": self.skill} if self.skill else dict(DEFAULT_ROBOT_MAPS))
            used = set(mapped) | {f"{t}_updates" for t in mapped} | {f"{t}_info" for t in mapped}
            d = self.detections
            if {d.topic, d.tf, d.tf_static} & (used | {"storey", "diagnostics"}):
                names = f"{d.topic!r}, {d.tf!r}, {d.tf_static!r}"
                msg = f"detection topics {names} clash with its map or storey topics"
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
            detections=self.detections.record() if self.detections is not None else None,
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
