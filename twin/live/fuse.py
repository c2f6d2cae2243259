"""Many robots, one twin: what an observation means once the twin's other sightings are counted.

Before an observation is planned (:mod:`twin.live.plan`), :func:`fuse` decides, for each element it
describes:

- **which element it is** (association): a robot's own IRI for something the twin already holds (the
  same storey, a compatible class, overlapping footprints and heights; dynamic elements only, never
  zones or structure) resolves to that element, and the robot's IRI becomes an alias of it;
- **whether it changes anything**: a box within the class's confirmation distance and angle of the held
  pose confirms it (nothing written); the confirmations' mean is committed only past a hysteresis;
  anything farther is a move, applied at once; a move onto another element of a compatible class merges
  the two;
- **whether it is news**: a change seen before the element's latest sighting or change is stale;
- **what was missed**: elements the observation's view (``a twin:View``) should have seen and did not
  collect misses; enough misses, from any robots over ``miss_span_s``, remove them.

It returns the reports to plan, rewritten to the elements they resolved to, and the in-memory effects
(sightings, misses, refinements), which the writer applies only once the plan is accepted.

Example::

    fused = fuse(observation, robot="robot2", rights=rights, live=live, states=states, shapes=shapes,
                 rules=config.fusion, arrival_ns=now, now_ns=now)
    plan = plan_observation(fused.reports, ..., sense_ns=fused.sense, reasons=fused.reasons)
    fused.apply(live.fusion)
"""

from __future__ import annotations

import datetime
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

from twin.config import FusionRules, Right
from twin.config.fusion import FusionClassRules
from twin.errors import ObservationError
from twin.fusion.footprints import (
    Pose,
    aligned,
    box_pose,
    centre_distance,
    heights_overlap,
    iou,
    yaw_difference,
)
from twin.fusion.memory import TENTATIVE_TTL_NS, Alias, FusionMemory, Miss, Refinement, Track
from twin.fusion.visibility import view_sees
from twin.graph.ifc_classes import supertypes
from twin.graph.store import GraphStore
from twin.live.state import ElementState, LiveState
from twin.records import ElementReport, Observation, ObservedBox, ObservedView, Shape
from twin.selection.skill_selection import VIRTUAL_TYPE

Effect = Callable[[FusionMemory], None]


@dataclass(slots=True)
class Fused:
    """An observation after fusion: what to plan, and what it did to the twin's memory of sightings."""

    reports: tuple[ElementReport, ...]
    resolved: dict[str, str] = field(default_factory=dict)
    """Robot IRI -> the element it is (only those that differ)."""
    stale: list[str] = field(default_factory=list)
    tentative: list[str] = field(default_factory=list)
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
        if self.refined:
            out["refined"] = list(self.refined)
        if self.merged:
            out["merged"] = dict(self.merged)
        return out


def load_fusion(store: GraphStore, now_ns: int) -> FusionMemory:
    """The aliases and the elements said to be distinct, as the graph keeps them (each alias counts as
    used now: its time to live starts again at every start)."""
    memory = FusionMemory()
    for r in store.select("SELECT ?a ?t WHERE { ?a twin:aliasOf ?t }"):
        memory.aliases[r["a"] or ""] = Alias(r["t"] or "", now_ns)
    for r in store.select("SELECT ?e WHERE { ?e twin:distinct true }"):
        memory.distinct.add(r["e"] or "")
    return memory


def expire_aliases(memory: FusionMemory, now_ns: int, ttl_ns: int) -> list[str]:
    """Forget the aliases unused for ``ttl_ns``; returns them (for the writer to delete from the graph)."""
    old = [a for a, v in memory.aliases.items() if now_ns - v.used_ns > ttl_ns]
    for a in old:
        del memory.aliases[a]
    for iri in [i for i, (_, since) in memory.tentative.items() if now_ns - since > TENTATIVE_TTL_NS]:
        del memory.tentative[iri]
    return sorted(old)


def _when(ns: int) -> str:
    return datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC).isoformat(timespec="milliseconds")


def is_candidate(state: ElementState) -> bool:
    """Whether fusion may associate, merge or remove by absence this element: dynamic, not a zone."""
    return not (
        state.removed
        or state.is_static
        or state.keepout
        or state.speed_limit
        or VIRTUAL_TYPE in state.ifc_types
    )


def compatible(schema: str, reported: str, state: ElementState) -> bool:
    """The reported class is the element's class, a supertype of it, or a subtype of it."""
    if reported in state.ifc_types:
        return True
    chain = supertypes(schema, reported)
    return chain is not None and state.ifc_class in chain


def _storey_poses(live: LiveState, storey: str) -> dict[str, Pose]:
    memory = live.fusion
    if memory.poses is None:
        memory.poses = {}
        for iri, state in live.states.items():
            index_element(live, iri, state)
    return memory.poses.get(storey, {})


def index_element(live: LiveState, iri: str, state: ElementState | None) -> None:
    """Keep the per-storey poses of candidate elements current after ``iri`` changed."""
    memory = live.fusion
    if memory.poses is None:
        return  # built on first use
    for poses in memory.poses.values():
        poses.pop(iri, None)
    if state is None or not is_candidate(state):
        return
    shape = live.maps.shape_of(iri)
    if shape is None:
        memory.shape_poses.pop(iri, None)
        return
    pose = memory.pose(iri, shape)
    storey = state.storey or storey_at(live, pose.zmin)
    if storey is not None:
        memory.poses.setdefault(storey, {})[iri] = pose


VIEW_INSET_M = 0.1
"""An element is in a view when its footprint, this much smaller on each side, is: a view's edge stops
at the walls, so an object against a wall is never wholly inside one."""

STOREY_TOLERANCE_M = 0.3
"""An element contained in a space (not a storey) stands on the highest storey whose elevation is at
most this far above its lowest point."""


def storey_at(live: LiveState, z: float) -> str | None:
    """The storey an element whose lowest point is at world ``z`` stands on."""
    best: tuple[float, str] | None = None
    for key, s in live.site.storeys.items():
        if s.elevation_m <= z + STOREY_TOLERANCE_M and (best is None or s.elevation_m > best[0]):
            best = (s.elevation_m, key)
    return None if best is None else best[1]


@dataclass(slots=True)
class _Context:
    robot: str
    rights: frozenset[Right]
    live: LiveState
    states: Mapping[str, ElementState]
    shapes: Mapping[str, Shape | None]
    rules: FusionRules
    base_iri: str
    pending: dict[str, tuple[str, Pose, ElementState]]
    """Elements created or moved earlier in this batch: iri -> (storey, pose, state)."""
    used: set[str] = field(default_factory=set)


def _report_pose(r: ElementReport, elevation: float) -> Pose | None:
    if r.box is None:
        return None
    b = r.box
    return box_pose(b.cx, b.cy, elevation + b.cz, b.sx, b.sy, b.sz, yaw=b.yaw)


def _held_pose(ctx: _Context, iri: str) -> Pose | None:
    pending = ctx.pending.get(iri)
    if pending is not None:
        return pending[1]
    shape = ctx.shapes[iri] if iri in ctx.shapes else ctx.live.maps.shape_of(iri)
    return None if shape is None else ctx.live.fusion.pose(iri, shape)


def _candidates(ctx: _Context, storey: str) -> dict[str, Pose]:
    out = dict(_storey_poses(ctx.live, storey))
    for iri, (s, pose, state) in ctx.pending.items():
        out.pop(iri, None)
        if s == storey and is_candidate(state):
            out[iri] = pose
    return out


def _matches(rules: FusionClassRules, a: Pose, b: Pose) -> float:
    """How well ``a`` matches ``b`` (0: not at all): their IoU, or for small objects a score by
    centre distance."""
    if not heights_overlap(a, b):
        return 0.0
    if max(a.sx, b.sx) < rules.small_object_m:
        d = centre_distance(a, b)
        return 0.0 if d > rules.centre_distance_m else 1.0 - d / max(rules.centre_distance_m, 1e-9) / 2
    value = iou(a, b)
    return value if value >= rules.min_iou else 0.0


def _associate(ctx: _Context, r: ElementReport, pose: Pose, storey: str) -> str | None:
    schema = ctx.live.site.schema
    best, best_score = None, 0.0
    for iri, held in _candidates(ctx, storey).items():
        if iri in ctx.used:
            continue
        state = ctx.states.get(iri)
        if state is None or not is_candidate(state) or not compatible(schema, r.ifc_class or "", state):
            continue
        rules = ctx.rules.of(state.ifc_types)
        score = _matches(rules, pose, held)
        if score > best_score:
            best, best_score = iri, score
    return best


def _confirms(rules: FusionClassRules, seen: Pose, held: Pose, *, sizes: bool, fraction: float = 1.0) -> bool:
    d = rules.confirm_distance_m * fraction
    if centre_distance(seen, held) > d or abs(seen.cz - held.cz) > d:
        return False
    if yaw_difference(seen, held) > rules.confirm_angle_rad * fraction:
        return False
    return not sizes or (
        abs(seen.sx - held.sx) <= d and abs(seen.sy - held.sy) <= d and abs(seen.sz - held.sz) <= d
    )


def _box_of(p: Pose, elevation: float) -> ObservedBox:
    return ObservedBox(p.cx, p.cy, p.cz - elevation, p.sx, p.sy, p.sz, p.yaw)


def _is_box_element(ctx: _Context, iri: str) -> bool:
    shape = ctx.shapes[iri] if iri in ctx.shapes else ctx.live.maps.shape_of(iri)
    return shape is not None and shape[0].vertices.shape == (8, 3)


def _merge_target(ctx: _Context, iri: str, state: ElementState, pose: Pose, storey: str) -> str | None:
    """Another element this one overlaps so much after its move that they are one object."""
    if iri in ctx.live.fusion.distinct:
        return None
    schema = ctx.live.site.schema
    for other, held in _candidates(ctx, storey).items():
        if other == iri or other in ctx.used or other in ctx.live.fusion.distinct:
            continue
        o_state = ctx.states.get(other)
        if o_state is None or not is_candidate(o_state):
            continue
        if not (compatible(schema, state.ifc_class, o_state) or compatible(schema, o_state.ifc_class, state)):
            continue
        if heights_overlap(pose, held) and iou(pose, held) >= ctx.rules.merge_iou:
            return other
    return None


def fuse(
    obs: Observation,
    *,
    robot: str,
    rights: frozenset[Right],
    live: LiveState,
    states: Mapping[str, ElementState],
    shapes: Mapping[str, Shape | None],
    pending: dict[str, tuple[str, Pose, ElementState]],
    rules: FusionRules,
    base_iri: str,
    arrival_ns: int,
    now_ns: int,
) -> Fused:
    """Resolve, classify and complete ``obs`` (see the module's docstring); ObservationError names a
    sense time too far in the future or an unknown view storey. ``pending`` (created and moved elements
    earlier in the batch) is updated with this observation's."""
    ctx = _Context(robot, rights, live, states, shapes, rules, base_iri, pending)
    memory = live.fusion
    view = obs.view
    default_sense = view.sense_ns if view is not None and view.sense_ns is not None else arrival_ns
    for sense in [r.sense_ns for r in obs.reports if r.sense_ns is not None] + [default_sense]:
        if sense > now_ns + rules.max_skew_ns:
            raise ObservationError(
                f"Observation sense time {_when(sense)} is in the future: the daemon's clock says "
                f"{_when(now_ns)} (allowed skew {rules.max_skew_ns / 1e9:g} s)."
            )
    if view is not None and view.storey not in live.site.storeys:
        known = ", ".join(sorted(live.site.storeys)) or "none"
        raise ObservationError(f"The view's storey {view.storey!r} is unknown; storeys: {known}.")
    out = Fused(reports=())
    reports: list[ElementReport] = []
    detected: set[str] = set()
    for given in obs.reports:
        r = given
        sense = r.sense_ns if r.sense_ns is not None else default_sense
        reported = r.iri
        target = r.iri
        alias = memory.aliases.get(r.iri)
        if alias is not None and not r.unmerge:
            target = alias.target
            out.resolved[r.iri] = target
            out.effects.append(_use_alias(r.iri, arrival_ns))
        state = states.get(target)
        exists = state is not None and not state.removed
        if r.unmerge:
            reports.append(r)
            out.sense[r.iri] = sense
            out.effects.append(_drop_alias(r.iri))
            out.unaliased.append(r.iri)
            out.notes.append(f"<{r.iri}> is its own element again (unmerged from <{target}>)")
            continue
        if not exists and state is not None and sense < max(state.sensed_ns, _seen(memory, target)):
            out.stale.append(r.iri)  # a sighting of what was removed after it was seen
            out.notes.append(f"stale: <{r.iri}> seen at {_when(sense)}, removed at {_when(state.sensed_ns)}")
            continue
        storey_key = r.storey or (state.storey if state is not None else None)
        storey = live.site.storeys.get(storey_key or "")
        pose = _report_pose(r, storey.elevation_m) if storey is not None else None
        if not exists and rules.enabled and pose is not None and storey_key is not None and not r.distinct:
            match = _associate(ctx, r, pose, storey_key)
            if match is not None:
                target = match
                state = states[match]
                exists = True
                if r.iri != match:
                    out.resolved[r.iri] = match
                    if memory.aliases.get(r.iri) is None or memory.aliases[r.iri].target != match:
                        out.aliases[r.iri] = match
                        out.effects.append(_set_alias(r.iri, match, arrival_ns))
                r = replace(r, ifc_class=None, classes=())
        if not exists:
            if alias is not None and target != r.iri:
                out.effects.append(_drop_alias(r.iri))
                out.unaliased.append(r.iri)
                out.resolved.pop(r.iri, None)
                target = r.iri
            if rules.tentative_sightings > 1 and (r.box is not None or r.geometry is not None):
                seen, since = memory.tentative.get(r.iri, (0, arrival_ns))
                if seen + 1 < rules.tentative_sightings:
                    out.tentative.append(r.iri)
                    out.effects.append(_count_tentative(r.iri, (seen + 1, since)))
                    continue
                out.effects.append(_count_tentative(r.iri, None))
            if r.distinct:
                out.effects.append(_mark_distinct(r.iri))
            reports.append(replace(r, iri=target))
            out.sense[target] = sense
            detected.add(target)
            out.effects.append(_sighting(target, robot, sense))
            if pose is not None and storey_key is not None and state is None:
                _pend(ctx, target, storey_key, pose, r=r, live=live)
            continue
        assert state is not None
        detected.add(target)
        ctx.used.add(target)
        track = memory.tracks.get(target)
        last = max(state.sensed_ns, track.seen_ns if track is not None else 0)
        r = replace(r, iri=target)
        if sense < last and _changes_something(r):
            out.stale.append(reported)
            out.notes.append(
                f"stale: <{target}> seen by {robot} at {_when(sense)}, the twin holds {_when(last)}"
            )
            out.effects.append(_sighting(target, robot, sense, latest=False))
            continue
        out.effects.append(_sighting(target, robot, sense))
        if rules.enabled and pose is not None and storey is not None and is_candidate(state):
            held = _held_pose(ctx, target)
            if held is not None:
                class_rules = rules.of(state.ifc_types)
                sizes = _is_box_element(ctx, target)
                if _confirms(class_rules, pose, held, sizes=sizes):
                    refinement = track.refinement if track is not None else None
                    sighted = aligned(pose, held)
                    mean = None
                    if refinement is not None and refinement.n + 1 >= rules.refine_after:
                        mean = _mean_with(refinement, sighted)
                    if mean is not None and not _confirms(
                        class_rules, mean, held, sizes=sizes, fraction=rules.refine_fraction
                    ):
                        r = replace(r, box=_box_of(mean, storey.elevation_m))
                        out.refined.append(target)
                        out.notes.append(
                            f"<{target}>: pose refined from {refinement.n + 1 if refinement else 1} sightings"
                        )
                        out.effects.append(_reset_refinement(target))
                        _pend(ctx, target, storey.key, mean, r=r, live=live)
                    else:
                        r = replace(r, box=None, storey=None)  # where it stood: on its storey too
                        out.effects.append(_refine(target, sighted))
                        if _only_sighting(r, state):
                            out.seen.append(target)
                            continue  # a confirmation: nothing to plan
                elif _unsure_move(rules, class_rules, pose, held, track, sizes=sizes):
                    # a short move seen once may be a detector's outlier: held until another agrees
                    agree = _agreeing(class_rules, pose, held, track, sizes=sizes) > 0
                    out.effects.append(_hold_move(target, aligned(pose, held), restart=not agree))
                    r = replace(r, box=None, storey=None)
                    if _only_sighting(r, state):
                        out.seen.append(target)
                        continue
                else:
                    out.effects.append(_reset_refinement(target))
                    if track is not None and track.moving is not None and not _far(rules, pose, held):
                        pose = _mean_with(track.moving, aligned(pose, held))  # the sightings that agreed
                        r = replace(r, box=_box_of(pose, storey.elevation_m))
                    other = _merge_target(ctx, target, state, pose, storey.key)
                    if other is not None and not (
                        target.startswith(base_iri) and not other.startswith(base_iri)
                    ):
                        reports.append(_merge(out, ctx, target, other, sense=sense, robot=robot))
                        r = replace(r, iri=other, ifc_class=None, classes=())
                        detected.add(other)
                        ctx.used.add(other)
                        o_held = _held_pose(ctx, other)
                        if o_held is not None and _confirms(
                            rules.of(states[other].ifc_types), pose, o_held, sizes=_is_box_element(ctx, other)
                        ):
                            r = replace(r, box=None, storey=None)
                    else:
                        _pend(ctx, target, storey.key, pose, r=r, live=live)
        if (
            r.ifc_class is not None
            and state.ifc_class.lower() != r.ifc_class.lower()
            and compatible(live.site.schema, r.ifc_class, state)
        ):
            r = replace(r, ifc_class=None)  # a robot's coarser or finer class for the same object
        reports.append(r)
        out.sense[r.iri] = sense
    if view is not None and rules.enabled and "dynamic" in rights:
        _absence(
            out,
            ctx,
            view=view,
            sightings=_sightings(obs, live),
            sense=default_sense,
            detected=detected,
            reports=reports,
        )
    out.reports = tuple(reports)
    return out


def _far(rules: FusionRules, seen: Pose, held: Pose) -> bool:
    return centre_distance(seen, held) > rules.certain_move_m


def _unsure_move(
    rules: FusionRules,
    class_rules: FusionClassRules,
    seen: Pose,
    held: Pose,
    track: Track | None,
    *,
    sizes: bool,
) -> bool:
    """A move shorter than ``certain_move_m`` that fewer than ``move_sightings`` sightings agree on
    (each within the confirmation distance and angle of their mean)."""
    if rules.move_sightings <= 1 or _far(rules, seen, held):
        return False
    return _agreeing(class_rules, seen, held, track, sizes=sizes) + 1 < rules.move_sightings


def _agreeing(
    class_rules: FusionClassRules, seen: Pose, held: Pose, track: Track | None, *, sizes: bool
) -> int:
    """How many held sightings of a move ``seen`` agrees with (0: it starts a new one)."""
    moving = track.moving if track is not None else None
    if moving is None or moving.n == 0:
        return 0
    return moving.n if _confirms(class_rules, aligned(seen, held), moving.mean(), sizes=sizes) else 0


def _only_sighting(r: ElementReport, state: ElementState) -> bool:
    """Nothing in ``r`` but what the element already is (its class), once its box confirmed it."""
    return (
        not _changes_something(r)
        and not r.labels
        and not r.materials
        and not r.classes
        and r.storey is None
        and not r.unmerge
        and (
            r.ifc_class is None
            or r.ifc_class in state.ifc_types
            or r.ifc_class.lower() == state.ifc_class.lower()
        )
    )


def _changes_something(r: ElementReport) -> bool:
    return (
        r.changes_geometry
        or r.removed
        or r.is_open is not None
        or r.keepout is not None
        or r.speed_limit is not None
    )


def _seen(memory: FusionMemory, iri: str) -> int:
    t = memory.tracks.get(iri)
    return 0 if t is None else t.seen_ns


def _mean_with(refinement: Refinement, pose: Pose) -> Pose:
    """The mean of ``refinement``'s sightings and ``pose`` (the held sums are left as they are)."""
    copy = refinement.copy()
    copy.add(pose)
    return copy.mean()


def _pend(ctx: _Context, iri: str, storey: str, pose: Pose, *, r: ElementReport, live: LiveState) -> None:
    state = ctx.states.get(iri)
    if state is None:  # created by this report: a candidate once planned (dynamic classes only)
        chain = supertypes(live.site.schema, r.ifc_class or "") or ()
        static = any(t in live.site.static_types for t in chain)
        state = ElementState(iri, chain[0] if chain else "", chain, static, storey=storey)
    ctx.pending[iri] = (storey, pose, state)


def _merge(out: Fused, ctx: _Context, gone: str, kept: str, *, sense: int, robot: str) -> ElementReport:
    """``gone`` is ``kept``: its IRI and aliases resolve to ``kept``; returns its removal to plan."""
    out.merged[gone] = kept
    out.reasons[gone] = f"merged into <{kept}>: seen by {robot} at {_when(sense)} where <{kept}> stands"
    out.notes.append(f"<{gone}> merged into <{kept}>")
    out.sense[gone] = sense
    out.aliases[gone] = kept
    out.effects.append(_set_alias(gone, kept, sense))
    for alias in ctx.live.fusion.aliases_of(gone):
        out.aliases[alias] = kept
        out.effects.append(_set_alias(alias, kept, sense))
    out.resolved[gone] = kept
    ctx.pending.pop(gone, None)
    out.effects.append(_forget(gone))
    return ElementReport(gone, removed=True)


def _sightings(obs: Observation, live: LiveState) -> list[Pose]:
    """The boxes an observation reports, as poses (whatever they resolve to)."""
    out = []
    for r in obs.reports:
        storey = live.site.storeys.get(r.storey or "")
        pose = _report_pose(r, storey.elevation_m) if storey is not None else None
        if pose is not None:
            out.append(pose)
    return out


def _absence(
    out: Fused,
    ctx: _Context,
    *,
    view: ObservedView,
    sightings: list[Pose],
    sense: int,
    detected: set[str],
    reports: list[ElementReport],
) -> None:
    memory = ctx.live.fusion
    held = _candidates(ctx, view.storey)
    looked: list[tuple[str, Pose, ElementState]] = []
    for iri, pose in held.items():
        if iri in detected or iri in out.merged:
            continue
        state = ctx.states.get(iri)
        if state is None or not is_candidate(state):
            continue
        if not any(d in state.ifc_types for d in view.detects):  # the element is of a class it detects
            continue
        looked.append((iri, pose, state))
    if not looked:
        return
    visible = view_sees(
        view,
        [pose for _, pose, _ in looked],
        iris=[iri for iri, _, _ in looked],
        held=held,
        sightings=sightings,
        elevation_m=ctx.live.site.storeys[view.storey].elevation_m,
        inset_m=VIEW_INSET_M,
    )
    for (iri, _, state), seen in zip(looked, visible, strict=True):
        if not seen:
            continue
        track = memory.tracks.get(iri)
        if sense <= max(state.sensed_ns, track.seen_ns if track is not None else 0):
            continue  # seen (or changed) at or after this view
        rules = ctx.rules.of(state.ifc_types)
        misses = [*(track.misses if track is not None else []), Miss(ctx.robot, sense)]
        span = max(m.sense_ns for m in misses) - min(m.sense_ns for m in misses)
        if len(misses) >= rules.misses_to_remove and span >= rules.miss_span_ns:
            robots = ", ".join(sorted({m.robot for m in misses}))
            out.reasons[iri] = (
                f"absent: not seen in {len(misses)} views by {robots} "
                f"between {_when(min(m.sense_ns for m in misses))} and {_when(sense)}"
            )
            out.notes.append(f"<{iri}> removed: {out.reasons[iri]}")
            out.sense[iri] = sense
            reports.append(ElementReport(iri, removed=True))
            out.effects.append(_forget(iri))
        else:
            out.effects.append(_miss(iri, ctx.robot, sense))


# --- effects on the memory (applied once the plan is accepted) -------------------------------------------


def _sighting(iri: str, robot: str, sense: int, *, latest: bool = True) -> Effect:
    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        if latest:
            t.sighted(robot, sense)
        else:  # a stale sighting is counted, never taken as the latest
            seen = t.seen_ns
            t.sighted(robot, sense)
            t.seen_ns = seen

    return run


def _miss(iri: str, robot: str, sense: int) -> Effect:
    return lambda m: m.track(iri).misses.append(Miss(robot, sense))


def _forget(iri: str) -> Effect:
    def run(m: FusionMemory) -> None:
        t = m.tracks.get(iri)
        if t is not None:
            t.misses.clear()
            t.refinement.n = 0

    return run


def _refine(iri: str, pose: Pose) -> Effect:
    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        t.refinement.add(pose)
        t.moving = None  # a confirmation: whatever seemed to move did not

    return run


def _hold_move(iri: str, pose: Pose, *, restart: bool) -> Effect:
    """Another sighting of a move not yet believed: added to those it agrees with, or a new start."""

    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        moving = t.moving
        if restart or moving is None:
            moving = Refinement()
        moving.add(pose)
        t.moving = moving

    return run


def _reset_refinement(iri: str) -> Effect:
    def run(m: FusionMemory) -> None:
        t = m.tracks.get(iri)
        if t is not None:
            t.refinement = Refinement()
            t.moving = None

    return run


def _set_alias(alias: str, target: str, now: int) -> Effect:
    def run(m: FusionMemory) -> None:
        m.aliases[alias] = Alias(target, now)

    return run


def _use_alias(alias: str, now: int) -> Effect:
    def run(m: FusionMemory) -> None:
        a = m.aliases.get(alias)
        if a is not None:
            a.used_ns = max(a.used_ns, now)

    return run


def _drop_alias(alias: str) -> Effect:
    def run(m: FusionMemory) -> None:
        m.aliases.pop(alias, None)

    return run


def _count_tentative(iri: str, seen: tuple[int, int] | None) -> Effect:
    def run(m: FusionMemory) -> None:
        if seen is not None:
            m.tentative[iri] = seen
        else:
            m.tentative.pop(iri, None)

    return run


def _mark_distinct(iri: str) -> Effect:
    return lambda m: m.distinct.add(iri)
