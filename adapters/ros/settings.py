"""The ROS 2 settings: ``[ros]``, the ROS keys of every ``[robots.NAME]`` (its namespace, topics,
domain, layouts and detections) and of every ``[sources.NAME]`` (its topic, doors, classes, levels).
The ROS side of the adapters owns these keys; the core knows a robot only by its name, ``rights`` and
``storey``, and a source by its name, ``kind`` and ``rights``.

The composition root (``adapters/cli/config_cmd.py``) hands these sections to the loader, so that a bad
key is refused when the file is loaded; the adapters read them with :func:`ros_robots`,
:func:`ros_sources` and ``cfg.section(RosSettings)``, which validate now if the loader was not given
them (the core's tests and tools).

Example::

    [robots.robot1]
    namespace = "/robot1"       # maps on /robot1/<topic> and /robot1/<topic>_updates
    storey = "ground-floor"     # the storey it starts on (the core's key; needed with a namespace)
    [robots.robot1.maps]        # topic under the namespace = skill (these two are the defaults)
    map = "localization"
    navigation_map = "navigation"
    [robots.robot1.full_every_s]  # for subscribers that do not apply updates (AMCL): full maps on
    map = 10.0                  # this topic at most every 10 s while its map changes

    [sources.building-doors]
    kind = "rmf_doors"               # DoorState on /door_states
    [sources.building-doors.doors]   # RMF door_name = the twin door's IRI, GlobalId or name
    main_entrance = "2O2Fr$t4X7Zf8NOew3FLOH"

    [sources.rmf-obstacles]
    kind = "rmf_obstacles"           # Obstacles on /rmf_obstacles
    classes = { human = "IfcBuildingElementProxy" }
    levels.L1 = { storey = "ground-floor", x = 0.0, y = 0.0, yaw_deg = 0.0 }

and in an adapter::

    for robot in ros_robots(cfg).values():   # every configured robot, by name
        if robot.namespace is not None: ...
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from twin.config import Config, ConfigSection, ConfigTable, SourceKind
from twin.config.base import Flag, Number, Text, Whole, list_of
from twin.config.tables import IfcClassName

RosLayout = Literal["bridge", "rmw_zenoh"]
Layouts = Annotated[tuple[RosLayout, ...], list_of('"bridge" and/or "rmw_zenoh"'), Field(min_length=1)]
DomainId = Annotated[Whole, Field(ge=0, le=232)]

DEFAULT_ROBOT_MAPS: tuple[tuple[str, str], ...] = (("map", "localization"), ("navigation_map", "navigation"))
"""A namespaced robot's topics when its table names none: AMCL reads ``map`` (its default
``map_topic``), so that carries the localization skill; the costmap's static layer is pointed at
``navigation_map`` (``map_topic: navigation_map``) for the navigation skill."""
RESERVED_TOPICS = ("storey",)
"""Topic names under a robot's namespace that the daemon uses for something else (``/<ns>/storey``)."""
DEFAULT_TOPICS: dict[str, str] = {"rmf_doors": "door_states", "rmf_obstacles": "rmf_obstacles"}
"""A source's topic when its table names none, by kind."""

_NAMESPACE = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*/?$")
_SOURCE_NAMESPACE = re.compile(r"^/?([A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*/?)?$")
_TOPIC = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


class RosSettings(ConfigSection):
    """``[ros]``: what ROS 2 robots see of the maps."""

    table = "ros"

    frame_id: Text = Field(
        "map", description="header.frame_id of the OccupancyGrid and PointCloud2 messages."
    )
    ingest_workers: Whole | None = Field(
        None,
        ge=0,
        le=64,
        description="Worker processes that decode the robots' detection arrays and TF and cut their views "
        "(each robot always in the same one); default the number of cores minus one, at least one; "
        "0: in the daemon's own ingest thread.",
    )
    ingest_queue: Whole = Field(
        1024,
        ge=16,
        le=1_000_000,
        description="Messages each ingestion queue (the ingest thread's, each worker's) holds at most; "
        "more are dropped and counted as overflow, by kind.",
    )
    tf_wait_s: Number = Field(
        0.5,
        ge=0.0,
        le=10.0,
        description="How long a detection array whose transform is not in yet waits for newer TF "
        "(then it is translated, or refused if it still does not resolve).",
    )

    hold_steady_ms: Number = Field(
        100.0,
        ge=0.0,
        le=1000.0,
        description="How long the daemon holds the detection arrays that only re-confirm what the "
        "robot's last array said (the same tracks, every box where it was within a detector's noise) to "
        "pass them to the twin in bunches, which cost the writer less CPU each; an array with any change "
        "passes at once, with what its robot held before it. 0: every array at once "
        "(docs/ros2-reporting.md).",
    )

    def workers(self) -> int:
        """``ingest_workers``, or the number of cores minus one (at least one)."""
        if self.ingest_workers is not None:
            return self.ingest_workers
        return max(1, (os.cpu_count() or 2) - 1)


# --- [robots.NAME] ------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class DetectionConfig:
    """``[robots.NAME.detections]``: the robot's ``vision_msgs/msg/Detection3DArray`` topic and how its
    detections become observations (see ``docs/ros2-reporting.md``)."""

    topic: str
    classes: tuple[tuple[str, str], ...]
    """``(class_id, IFC class)`` pairs."""
    types: tuple[tuple[str, str], ...] = ()
    """``(class_id, descriptive type IRI)`` pairs (``furn:Chair`` expanded), for the ids that give one."""
    min_score: float = 0.5
    fov_deg: float = 90.0
    range_m: float = 5.0
    rays: int = 64
    max_tilt_deg: float = 15.0
    max_detections: int = 256
    future_s: float = 2.0
    session_gap_s: float = 10.0
    map_frame: str = "map"
    sensor_frame: str | None = None
    z_reference: Literal["storey", "building"] = "storey"
    view_skill: str | None = "localization"
    tf: str = "tf"
    tf_static: str = "tf_static"
    diagnostics: bool = False
    optical: bool = False
    vfov_deg: float | None = None
    near_m: float = 0.0
    heights_m: tuple[float, float] = (0.1, 0.5)
    camera_info: str | None = None


@dataclass(frozen=True, slots=True)
class RosRobot:
    """A configured robot as ROS 2 sees it: with a ``namespace``, the maps it receives.

    ``maps`` pairs a topic name under the namespace with a skill, e.g. ``(("map", "localization"),
    ("navigation_map", "navigation"))``: each topic carries that skill's map of the robot's current
    ``storey`` (latched), and ``<topic>_updates`` its changed rectangles. Without a namespace: no
    topics; its ``storey`` (the one it starts on, as the writer has it) is still its storey key's
    answer over Zenoh.
    """

    name: str
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


_TYPE_PREFIXES = {
    "furn:": "http://pi.pauwel.be/voc/furniture#",
    "beo:": "https://pi.pauwel.be/voc/buildingelement#",
}


def _type_iri(value: str) -> str:
    for prefix, iri in _TYPE_PREFIXES.items():
        if value.startswith(prefix) and len(value) > len(prefix):
            return iri + value.removeprefix(prefix)
        if value.startswith(iri) and len(value) > len(iri):
            return value
    msg = f"expected a descriptive type such as furn:Chair or beo:Door (FURN or BEO), got {value!r}"
    raise ValueError(msg)


class DetectedClassTable(ConfigTable):
    """One class id of ``[robots.NAME.detections] classes`` with a descriptive type:
    ``chair = { ifc = "IfcFurniture", type = "furn:Chair" }``."""

    ifc: IfcClassName = Field(description="The IFC class of what the detector reports as this id.")
    type: Text = Field(description="Its descriptive type (furn:Chair, furn:Table, beo:Door ...).")

    @field_validator("type")
    @classmethod
    def _type(cls, value: str) -> str:
        return _type_iri(value)


class DetectionTable(ConfigTable):
    """``[robots.NAME.detections]``: subscribe to the robot's detections (needs its ``namespace``)."""

    topic: Text = Field(
        "detections", description='Detection3DArray topic under the namespace ("/name": absolute).'
    )
    classes: dict[str, IfcClassName | DetectedClassTable] = Field(
        description='class_id -> IFC class, e.g. { table = "IfcFurniture" }, or with a descriptive type '
        '(association then tells a chair from a table): { chair = { ifc = "IfcFurniture", '
        'type = "furn:Chair" } }; other classes are ignored.',
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
    vfov_deg: (
        Annotated[Number, Field(gt=0, le=180, description="Vertical field of view (default: none).")] | None
    ) = None
    optical: Flag = Field(
        False,
        description="The sensor frame looks along +z (x right, y down: a camera's optical frame, REP 103); "
        "false: along +x (x forward, y left, z up). Never guessed from the frame's name.",
    )
    near_m: Annotated[
        Number, Field(ge=0, le=100, description="Blind zone: the detector sees nothing nearer, m.")
    ] = 0.0
    heights_m: Annotated[tuple[Number, Number], list_of("two heights, low and high, in m")] = Field(
        (0.1, 0.5),
        description="Heights above the floor the camera's frame must hold for a place to be in its view "
        "(the band where the detected classes stand).",
    )
    camera_info: Text | None = Field(
        None,
        description='sensor_msgs/CameraInfo topic under the namespace (e.g. "camera/camera_info"): its '
        "K, width and height give both fields of view once it is received.",
    )
    max_tilt_deg: Annotated[Number, Field(ge=0, le=90, description="Boxes tilted more are refused.")] = 15.0
    max_detections: Annotated[Whole, Field(ge=1, le=10_000)] = 256
    future_s: Annotated[Number, Field(ge=0, le=3600, description="Clock skew allowed for stamps.")] = 2.0
    session_gap_s: Annotated[
        Number,
        Field(
            gt=0,
            le=86400,
            description="Arrays stamped further apart are two tracker sessions (ids then name new objects).",
        ),
    ] = 10.0
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

    @field_validator("heights_m")
    @classmethod
    def _heights(cls, heights: tuple[float, float]) -> tuple[float, float]:
        lo, hi = heights
        if not 0 <= lo <= hi <= 10:
            msg = f"expected [low, high] heights with 0 <= low <= high <= 10 m, got [{lo}, {hi}]"
            raise ValueError(msg)
        return heights

    @field_validator("topic", "tf", "tf_static", "camera_info")
    @classmethod
    def _topic(cls, topic: str | None) -> str | None:
        if topic is None:
            return None
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
            classes=tuple((k, v if isinstance(v, str) else v.ifc) for k, v in self.classes.items()),
            types=tuple((k, v.type) for k, v in self.classes.items() if not isinstance(v, str)),
            min_score=self.min_score,
            fov_deg=self.fov_deg,
            range_m=self.range_m,
            rays=self.rays,
            max_tilt_deg=self.max_tilt_deg,
            max_detections=self.max_detections,
            future_s=self.future_s,
            session_gap_s=self.session_gap_s,
            map_frame=self.map_frame,
            sensor_frame=self.sensor_frame or None,
            z_reference=self.z_reference,
            view_skill=self.view_skill,
            tf=self.tf,
            tf_static=self.tf_static,
            diagnostics=self.diagnostics,
            optical=self.optical,
            vfov_deg=self.vfov_deg,
            near_m=self.near_m,
            heights_m=(float(self.heights_m[0]), float(self.heights_m[1])),
            camera_info=self.camera_info or None,
        )


class RosRobotSettings(ConfigSection):
    """The ROS 2 keys of ``[robots.NAME]``. Skill names are checked against the configured skills,
    which the loader passes as the validation context ``{"skills": names}``. ``storey`` is the core's
    key, read here: a robot with a namespace needs it."""

    table = "robots"
    each: ClassVar[bool] = True

    namespace: Text | None = Field(None, description='ROS namespace of its maps, e.g. "/robot1".')
    storey: Text | None = Field(None, description="The storey key it starts on (needed with a namespace).")
    maps: dict[str, Text] | None = Field(
        None, description="Topic under the namespace = skill; default: map = localization, "
        "navigation_map = navigation.",
    )  # fmt: skip
    skill: Text | None = Field(None, description='The old form of maps = { map = "SKILL" }.')
    domain_id: DomainId = 0
    ros: Layouts = ("bridge", "rmw_zenoh")
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
    def _together(self) -> RosRobotSettings:
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
            if self.namespace is None:
                msg = (
                    f"full_every_s applies to a robot's ROS 2 map topics ({', '.join(sorted(topics))}), and "
                    'this robot has none without a namespace: add namespace = "/<robot>" (and storey)'
                )
                raise ValueError(msg)
            if unknown:
                msg = (
                    f"full_every_s names {', '.join(map(repr, unknown))}, not a map topic of this robot "
                    f"(its topics: {', '.join(sorted(topics))})"
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
            if {d.topic, d.tf, d.tf_static, d.camera_info} & (used | {"storey", "diagnostics"}):
                names = f"{d.topic!r}, {d.tf!r}, {d.tf_static!r}"
                msg = f"detection topics {names} clash with its map or storey topics"
                raise ValueError(msg)
        return self

    def record(self, name: str) -> RosRobot:
        """The robot ``name`` as the ROS side uses it."""
        ns = self.namespace
        if self.skill is not None:
            maps: tuple[tuple[str, str], ...] = (("map", self.skill),)
        elif self.maps is not None:
            maps = tuple(self.maps.items())
        else:
            maps = DEFAULT_ROBOT_MAPS if ns is not None else ()
        return RosRobot(
            name=name,
            namespace=("/" + ns.strip("/")) if ns else None,
            maps=maps,
            storey=self.storey,
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


# --- [sources.NAME] -----------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class LevelConfig:
    """An RMF level: the storey it is, and ``twin_from_level`` (x, y in metres, yaw in radians)."""

    storey: str
    x: float = 0.0
    y: float = 0.0
    yaw_rad: float = 0.0


@dataclass(frozen=True, slots=True)
class RosSource:
    """A configured building system (``[sources.NAME]``) as ROS 2 sees it: the topic it publishes and
    how its messages become observations."""

    name: str
    kind: SourceKind
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


class RosSourceSettings(ConfigSection):
    """The ROS 2 keys of ``[sources.NAME]`` (its ``kind`` and ``rights`` are the core's)."""

    table = "sources"
    each: ClassVar[bool] = True

    topic: Text | None = Field(None, description="Default: door_states / rmf_obstacles.")
    namespace: Text = Field("/", description='ROS namespace of the topic, e.g. "/" or "/building".')
    domain_id: DomainId = 0
    ros: Layouts = ("bridge", "rmw_zenoh")
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
        if not _SOURCE_NAMESPACE.match(ns):
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

    def record(self, name: str, kind: SourceKind) -> RosSource:
        return RosSource(
            name=name,
            kind=kind,
            topic=self.topic or DEFAULT_TOPICS[kind],
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


ROS_SECTIONS: tuple[type[ConfigSection], ...] = (RosSettings, RosRobotSettings, RosSourceSettings)
"""The ROS side's sections, for the composition root."""


def ros_robots(cfg: Config) -> dict[str, RosRobot]:
    """Every configured robot (``[robots.NAME]``) as the ROS side uses it, by name (a
    :class:`~twin.errors.ConfigError` naming the robot and key if its ROS keys are bad)."""
    return {name: table.record(name) for name, table in cfg.each(RosRobotSettings).items()}


def ros_sources(cfg: Config) -> dict[str, RosSource]:
    """Every configured building system (``[sources.NAME]``) as the ROS side uses it, by name."""
    sources = cfg.each(RosSourceSettings)
    return {name: table.record(name, cfg.sources[name].kind) for name, table in sources.items()}
