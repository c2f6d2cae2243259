"""What the live twin knows of each element beyond its geometry, held in memory.

Loaded once from the graph (:func:`load_states`) and kept current by the writer after each commit, so
that the hot path (re-confirmations, rights, skill selection) needs no query.

Example::

    states = load_states(store)
    states["https://example.org/building-twin/lab#door_..."].is_door     # True
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from twin.config import Right
from twin.fusion.memory import FusionMemory
from twin.graph.rdf import Object
from twin.graph.store import GraphStore
from twin.live.live_maps import LiveMaps
from twin.live.parse import sense_time_ns
from twin.selection.skills import SkillProfile


@dataclass(frozen=True, slots=True)
class ElementState:
    """One element: identity, classes, the values selections look at, and its door state."""

    iri: str
    ifc_class: str
    ifc_types: tuple[str, ...]
    """The IFC class and its supertypes (``twin:ifcType``)."""
    is_static: bool
    name: str = ""
    storey: str | None = None
    is_open: bool | None = None
    removed: bool = False
    keepout: bool = False
    speed_limit: int = 0
    """Percent of maximum speed inside the element (``twin:speedLimit``); 0: no limit."""
    classes: frozenset[str] = frozenset()
    """Every ``rdf:type`` IRI (``bot:Element``, ``beo:Wall``, ``furn:Table`` ...)."""
    labels: frozenset[str] = frozenset()
    materials: frozenset[str] = frozenset()
    facing_materials: frozenset[str] = frozenset()
    """What a sensor faces (``twin:facingMaterial``): what skills exclude by."""
    sensed_ns: int = 0
    """When its last applied change (or removal) was seen (``twin:senseTime``, ns); 0: never observed."""

    @property
    def is_door(self) -> bool:
        return "IfcDoor" in self.ifc_types

    @property
    def change_right(self) -> Right:
        """The right a robot needs to change or remove it: ``static`` for a static element, else
        ``dynamic``."""
        return "static" if self.is_static else "dynamic"


@dataclass(frozen=True, slots=True)
class StoreyFrame:
    key: str
    iri: str
    elevation_m: float


@dataclass(frozen=True, slots=True)
class SiteFrame:
    """The fixed facts an observation is checked against (they do not change while the daemon runs)."""

    storeys: dict[str, StoreyFrame]
    schema: str
    static_types: tuple[str, ...]
    site_box: tuple[float, float, float, float, float, float]
    """World ``xmin, ymin, zmin, xmax, ymax, zmax`` observed geometry must lie in (margin included)."""
    model_iri: str


_SEP = "\u001f"  # unit separator: never in an IRI, rare in a label


def _set(value: str | None) -> frozenset[str]:
    return frozenset(v for v in (value or "").split(_SEP) if v)


def _sense_ns(text: str | None) -> int:
    if not text:
        return 0
    try:
        return sense_time_ns(text)
    except ValueError:
        return 0


def load_states(store: GraphStore, iris: Sequence[str] | None = None) -> dict[str, ElementState]:
    """Every element's (or only those of ``iris``) classes, static flag, names, materials, storey, door
    state and removal."""
    values = "" if iris is None else "VALUES ?e { " + " ".join(f"<{i}>" for i in iris) + " }"
    rows = store.select(
        f"""SELECT ?e ?cls ?static (SAMPLE(?key) AS ?storey) (SAMPLE(?open) AS ?isOpen)
                  (SAMPLE(?gone) AS ?removed) (SAMPLE(?keep) AS ?keepout) (SAMPLE(?speed) AS ?speedLimit)
                  (SAMPLE(?sense) AS ?senseTime)
                  (GROUP_CONCAT(DISTINCT ?t; separator="{_SEP}") AS ?types)
                  (GROUP_CONCAT(DISTINCT STR(?c); separator="{_SEP}") AS ?classes)
                  (GROUP_CONCAT(DISTINCT ?n; separator="{_SEP}") AS ?labels)
                  (GROUP_CONCAT(DISTINCT ?m; separator="{_SEP}") AS ?materials)
                  (GROUP_CONCAT(DISTINCT ?f; separator="{_SEP}") AS ?facing) WHERE {{
             {values}
             ?e a bot:Element ; twin:ifcClass ?cls .
             OPTIONAL {{ ?e a ?c }}
             OPTIONAL {{ ?e twin:isStatic ?static }}
             OPTIONAL {{ ?e twin:ifcType ?t }}
             OPTIONAL {{ ?e rdfs:label ?n }}
             OPTIONAL {{ ?e twin:material ?m }}
             OPTIONAL {{ ?e twin:facingMaterial ?f }}
             OPTIONAL {{ ?st twin:storeyKey ?key ; bot:containsElement ?e }}
             OPTIONAL {{ ?e twin:isOpen ?open }}
             OPTIONAL {{ ?e twin:removed ?gone }}
             OPTIONAL {{ ?e twin:keepout ?keep }}
             OPTIONAL {{ ?e twin:speedLimit ?speed }}
             OPTIONAL {{ ?e twin:senseTime ?sense }}
           }} GROUP BY ?e ?cls ?static"""
    )
    out = {}
    for r in rows:
        iri = r["e"] or ""
        cls = r["cls"] or ""
        types = [t for t in (r["types"] or cls).split(_SEP) if t]
        labels = _set(r["labels"])
        out[iri] = ElementState(
            iri=iri,
            ifc_class=cls,
            ifc_types=(cls, *(t for t in types if t != cls)),
            is_static=r["static"] in ("true", "1"),
            name=min(labels) if labels else "",
            storey=r["storey"],
            is_open=None if r["isOpen"] is None else r["isOpen"] in ("true", "1"),
            removed=r["removed"] in ("true", "1"),
            keepout=r["keepout"] in ("true", "1"),
            speed_limit=int(r["speedLimit"] or 0),
            classes=_set(r["classes"]),
            labels=labels,
            materials=_set(r["materials"]),
            facing_materials=_set(r["facing"]),
            sensed_ns=_sense_ns(r["senseTime"]),
        )
    return out


@dataclass(slots=True)
class Sighting:
    """The latest report of an element, changed or not (kept in memory only: it changes many times a
    second and the graph does not grow with how often an element is seen)."""

    robot: str
    stamp_ns: int


@dataclass(eq=False, slots=True)
class LiveState:
    """Everything the twin's writer changes. Only the writer thread mutates it; other threads read
    single attributes (a revision, a dict lookup), never iterate it while the writer runs."""

    site: SiteFrame
    maps: LiveMaps
    states: dict[str, ElementState]
    skills: dict[str, SkillProfile]
    revision: int
    last_seen: dict[str, Sighting]
    held: dict[str, dict[str, Object | None]]
    """Subject -> predicate -> the exact object of each single-valued triple the writer last wrote (so
    that the next change deletes that triple exactly instead of by a pattern)."""
    fusion: FusionMemory = field(default_factory=FusionMemory)
    robot_storeys: dict[str, str] = field(default_factory=dict)
    """Configured robot -> the storey it is on (configured at start, switched by storey requests)."""
    """What robots saw and missed of each element, and the robot IRIs that resolved to elements."""

    def advance(self, revision: int) -> None:
        """The twin is at ``revision`` now: the one place the revision moves (it never goes back)."""
        if revision < self.revision:
            msg = f"The twin's revision cannot go back from {self.revision} to {revision}."
            raise ValueError(msg)
        self.revision = revision
