"""What fusion decides for one observation (:class:`Fused`), and what it decides with
(:class:`FusionContext`).

:func:`twin.live.fuse.fuse` builds one :class:`FusionContext` per observation; each rule under
:mod:`twin.fusion` reads the twin through it and writes its decisions into ``ctx.out`` (a :class:`Fused`):
the reports left to plan, the IRIs resolved, the stale and tentative ones, the notes for the event log,
and the effects on the memory (applied by the writer once the plan is accepted).

Example::

    ctx = FusionContext(robot, rights, live, states, shapes, rules, base_iri, pending, arrival_ns=now)
    ctx.candidates("ground-floor")       # the elements fusion may match there, with their poses
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from twin.config import FusionRules, Right
from twin.fusion.effects import Effect, decided
from twin.fusion.footprints import Pose, box_pose
from twin.fusion.gates import is_candidate
from twin.fusion.memory import FusionMemory
from twin.fusion.poses import storey_arrays, storey_poses
from twin.graph.ifc_classes import supertypes
from twin.records import ElementReport, FloatArray, Shape

if TYPE_CHECKING:
    from twin.live.state import ElementState, LiveState


Pending = dict[str, tuple[str, Pose, "ElementState"]]
"""Elements created or moved earlier in a batch: iri -> (storey, pose, state)."""


@dataclass(slots=True)
class Fused:
    """An observation after fusion: what to plan, and what it did to the twin's memory of sightings."""

    reports: tuple[ElementReport, ...]
    resolved: dict[str, str] = field(default_factory=dict)
    """Robot IRI -> the element it is (only those that differ)."""
    stale: list[str] = field(default_factory=list)
    tentative: list[str] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    """Elements whose reported move (or resize) is noted but not yet confirmed."""
    sense: dict[str, int] = field(default_factory=dict)
    """Element -> when the change planned for it was seen (ns)."""
    reasons: dict[str, str] = field(default_factory=dict)
    """Element removed by fusion -> why (absence, merge)."""
    merged: dict[str, str] = field(default_factory=dict)
    """Element merged into another -> the one it is now."""
    aliases: dict[str, str] = field(default_factory=dict)
    """New aliases: robot IRI -> element."""
    unaliased: list[str] = field(default_factory=list)
    """Aliases to forget (the IRI is an element of its own now)."""
    refined: list[str] = field(default_factory=list)
    seen: list[str] = field(default_factory=list)
    """Elements confirmed where they stand (no report left to plan for them)."""
    notes: list[str] = field(default_factory=list)
    """What fusion decided, for the event log (merges, refinements, removals by absence, stale)."""
    effects: list[Effect] = field(default_factory=list)

    def apply(self, memory: FusionMemory) -> None:
        """Apply the in-memory effects (call once the plan is accepted)."""
        for effect in self.effects:
            effect(memory)

    def ack(self) -> dict[str, object]:
        out: dict[str, object] = {}
        if self.resolved:
            out["resolved"] = dict(self.resolved)
        if self.stale:
            out["stale"] = list(self.stale)
        if self.tentative:
            out["tentative"] = list(self.tentative)
        if self.pending:
            out["pending"] = list(dict.fromkeys(self.pending))
        if self.refined:
            out["refined"] = list(self.refined)
        if self.merged:
            out["merged"] = dict(self.merged)
        return out


@dataclass(slots=True)
class FusionContext:
    """The twin as one observation's fusion sees it: the robot, the states and shapes as the batch left
    them, the rules, and the decisions so far (``out``, ``reports``, ``detected``, ``used``)."""

    robot: str
    rights: frozenset[Right]
    live: LiveState
    states: Mapping[str, ElementState]
    shapes: Mapping[str, Shape | None]
    rules: FusionRules
    base_iri: str
    pending: Pending
    arrival_ns: int
    content_lag_ns: int = 0
    """How much older than its (corrected) sense time a report's content may be: the robot's clock
    correction when it moved sense times later (a robot whose reports are always late looks like one
    whose clock is behind). Comparisons with previous poses use the earlier reading."""
    out: Fused = field(default_factory=lambda: Fused(reports=()))
    reports: list[ElementReport] = field(default_factory=list)
    """The reports left to plan, rewritten to the elements they resolved to."""
    detected: set[str] = field(default_factory=set)
    """Elements this observation describes (never missed by its view)."""
    used: set[str] = field(default_factory=set)
    """Elements already matched by a report of this observation (matched at most once; a partial view
    of an element, :func:`twin.fusion.associate.seen_within`, does not match it)."""
    contested: set[str] = field(default_factory=set)
    """Robot IRIs whose alias names an element another report of this observation is nearer
    (:func:`twin.fusion.associate.contested_aliases`): dropped, associated afresh."""
    box_list: list[tuple[str, ElementReport, Pose]] = field(default_factory=list)
    """:attr:`boxes` made so far."""
    boxes_later: Callable[[], list[tuple[str, ElementReport, Pose]]] | None = None
    """Boxes to add to :attr:`boxes` when something reads them (confirmations at once make their
    poses only if absence looks at them)."""
    bias: tuple[float, float] | None = None
    """The robot's detector bias (:func:`twin.fusion.bias.unbiased`), once ``bias_known``."""
    bias_known: bool = False
    streaming: bool = False
    """The robot streams views and this observation has one (:func:`twin.fusion.tentative.streams`)."""
    held_seen: set[str] = field(default_factory=set)
    """Held new objects (robot IRIs) this observation saw again under another IRI."""

    @property
    def memory(self) -> FusionMemory:
        return self.live.fusion

    @property
    def boxes(self) -> list[tuple[str, ElementReport, Pose]]:
        """Every box this observation reports: (storey, the report as given, its world pose)."""
        if self.boxes_later is not None:
            later, self.boxes_later = self.boxes_later, None
            self.box_list.extend(later())
        return self.box_list

    def shape_of(self, iri: str) -> Shape | None:
        return self.shapes[iri] if iri in self.shapes else self.live.maps.shape_of(iri)

    def held_pose(self, iri: str) -> Pose | None:
        """The pose the twin holds for ``iri`` (as changed earlier in the batch)."""
        pending = self.pending.get(iri)
        if pending is not None:
            return pending[1]
        shape = self.shape_of(iri)
        return None if shape is None else self.memory.pose(iri, shape)

    def candidates(self, storey: str) -> dict[str, Pose]:
        """Element -> pose of every element on ``storey`` fusion may match (as the batch left them)."""
        out = dict(storey_poses(self.live, storey))
        for iri, (s, pose, state) in self.pending.items():
            out.pop(iri, None)
            if s == storey and is_candidate(state):
                out[iri] = pose
        return out

    def candidates_near(self, storey: str, lo: FloatArray, hi: FloatArray) -> dict[str, Pose]:
        """:meth:`candidates` less those whose centre lies farther than half their footprint's sizes
        (x + y) from the box ``lo``..``hi`` (the same elements, in the same order)."""
        arrays = storey_arrays(self.live, storey)
        out = {arrays.iris[i]: arrays.poses[i] for i in arrays.near(lo, hi).tolist()}
        for iri, (s, pose, state) in self.pending.items():
            out.pop(iri, None)
            r = (pose.sx + pose.sy) / 2
            if (
                s == storey
                and is_candidate(state)
                and lo[0] - r <= pose.cx <= hi[0] + r
                and lo[1] - r <= pose.cy <= hi[1] + r
            ):
                out[iri] = pose
        return out

    def earliest(self, sense: int) -> int:
        """The earliest a report sensed at ``sense`` (corrected) may have been seen."""
        return sense - self.content_lag_ns

    def decide(self, iri: str, rule: str) -> None:
        """Note the rule that decided ``iri``'s report (``twin explain`` shows the latest)."""
        self.out.effects.append(decided(iri, rule))

    def is_box_element(self, iri: str) -> bool:
        shape = self.shape_of(iri)
        return shape is not None and shape[0].vertices.shape == (8, 3)

    def pend(self, iri: str, storey: str, pose: Pose, *, r: ElementReport) -> None:
        """``iri`` stands at ``pose`` once this observation is planned (for the rest of the batch)."""
        state = self.states.get(iri)
        if state is None:  # created by this report: a candidate once planned (dynamic classes only)
            from twin.live.state import ElementState  # noqa: PLC0415  (twin.live imports twin.fusion)

            chain = supertypes(self.live.site.schema, r.ifc_class or "") or ()
            static = any(t in self.live.site.static_types for t in chain)
            state = ElementState(iri, chain[0] if chain else "", chain, static, storey=storey)
        self.pending[iri] = (storey, pose, state)


def report_pose(r: ElementReport, elevation: float) -> Pose | None:
    """The world pose of a report's box (its ``cz`` is above the storey's ``elevation``)."""
    if r.box is None:
        return None
    b = r.box
    return box_pose(b.cx, b.cy, elevation + b.cz, b.sx, b.sy, b.sz, yaw=b.yaw)
