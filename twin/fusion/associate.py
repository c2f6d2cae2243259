"""Association: which element a robot's report is.

A robot's IRI that is an alias resolves to its element. An IRI the twin does not know, with a box on
a storey, resolves to the best-matching candidate element there (:mod:`twin.fusion.gates`), and becomes
an alias of it. What resolves to nothing is a new element (held tentative until seen often enough:
:mod:`twin.fusion.tentative`).

Example::

    target, alias = through_alias(ctx, r)
    found = associate(ctx, r, pose, "ground-floor")   # found.target: the element it is
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

from twin.fusion.confirm import box_of
from twin.fusion.effects import (
    confirmed_by,
    count_tentative,
    drop_alias,
    mark_distinct,
    set_alias,
    sighting,
    use_alias,
)
from twin.fusion.footprints import Pose, centre_distance, heights_overlap, iou
from twin.fusion.gates import compatible, is_candidate, kinds_agree, lies_within, matches, sizes_agree
from twin.fusion.memory import Alias
from twin.fusion.tentative import held_back
from twin.records import ElementReport

if TYPE_CHECKING:
    from collections.abc import Sequence

    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState


def through_alias(ctx: FusionContext, r: ElementReport) -> tuple[str, Alias | None]:
    """The element ``r``'s IRI stands for (itself unless an alias), and the alias."""
    alias = ctx.memory.aliases.get(r.iri)
    if alias is None or r.unmerge:
        return r.iri, alias
    ctx.out.resolved[r.iri] = alias.target
    ctx.out.effects.append(use_alias(r.iri, ctx.arrival_ns))
    return alias.target, alias


@dataclass(frozen=True, slots=True)
class Association:
    """What a report resolved to: an element (``target``), or one it is a partly hidden view of
    (``within``: its box fails only the size gate and lies inside the element's footprint). Neither: a
    separate object, which never resizes, moves or merges an element it overlaps."""

    target: str | None = None
    within: str | None = None


def alias_fits(
    ctx: FusionContext, r: ElementReport, state: ElementState, pose: Pose
) -> Literal["fits", "within", "fails"]:
    """Whether a report through an alias still fits the element it resolved to: its class and kind
    agree, it is no farther than ``alias_jump_m`` and its size agrees (``"within"``: smaller, inside the
    element's footprint, a partly hidden view of it). A reused tracker id fails."""
    held = ctx.held_pose(state.iri)
    schema = ctx.live.site.schema
    if held is None or not is_candidate(state):
        return "fits"  # nothing to compare with (a door, structure: the alias is as good as the IRI)
    if r.ifc_class is not None and not compatible(schema, r.ifc_class, state):
        return "fails"
    if not kinds_agree(schema, r.classes, r.ifc_class, state):
        return "fails"
    if centre_distance(pose, held) > ctx.rules.alias_jump_m or not heights_overlap(pose, held):
        return "fails"
    rules = ctx.rules.of(state.ifc_types)
    if sizes_agree(rules, pose, held):
        return "fits"
    return "within" if lies_within(pose, held, margin_m=rules.confirm_distance_m) else "fails"


def contested_aliases(ctx: FusionContext, reports: Sequence[ElementReport]) -> set[str]:
    """The robot IRIs of ``reports`` (one observation) whose alias names an element that another of
    its reports names too: an element is one object, so it keeps the report by its own IRI, else the one
    nearest the pose it holds; the others' aliases are contested (dropped, associated afresh). Two
    chairs once seen as one never drag their element back and forth between them."""
    aliases = ctx.memory.aliases
    named = [(r, aliases.get(r.iri)) for r in reports if r.box is not None and not r.unmerge]
    targets = [r.iri if alias is None else alias.target for r, alias in named]
    out: set[str] = set()
    if len(set(targets)) == len(targets):
        return out  # every element named once (the common case)
    claims: dict[str, list[ElementReport]] = {}
    for (r, _), target in zip(named, targets, strict=True):
        claims.setdefault(target, []).append(r)
    for target, rs in claims.items():
        if len(rs) < 2 or all(r.iri == target for r in rs):
            continue
        held = ctx.held_pose(target)
        if held is None:
            continue
        own = [r for r in rs if r.iri == target]
        far = [math.hypot(r.box.cx - held.cx, r.box.cy - held.cy) if r.box else math.inf for r in rs]
        keep = own[0] if own else rs[far.index(min(far))]
        out.update(r.iri for r in rs if r is not keep)
    return out


def drop_failed_alias(ctx: FusionContext, r: ElementReport, target: str) -> None:
    """``r`` came through an alias it does not fit: the alias is dropped, ``r`` is associated afresh."""
    ctx.out.resolved.pop(r.iri, None)
    ctx.out.effects.append(drop_alias(r.iri))
    ctx.out.unaliased.append(r.iri)
    ctx.out.notes.append(
        f"<{r.iri}> is no longer <{target}>: its report does not fit it (another object, e.g. a reused "
        "tracker id); associated afresh"
    )


def associate(ctx: FusionContext, r: ElementReport, pose: Pose, storey: str) -> Association:
    """Which candidate element on ``storey`` ``r`` (at ``pose``) is: the best match of a compatible class
    and kind, overlapping footprint and height, and compatible size (:mod:`twin.fusion.gates`), not
    matched yet by this observation. Else the element it is a partly hidden view of (it fails only the
    size gate and lies inside the footprint), matched or not: a partial view neither is an object of its
    own nor takes the element from the full report of it in the same observation."""
    schema = ctx.live.site.schema
    best, best_score = None, 0.0
    within, within_score = None, -1.0
    for iri, held in ctx.candidates(storey).items():
        state = ctx.states.get(iri)
        if state is None or not is_candidate(state) or not compatible(schema, r.ifc_class or "", state):
            continue
        if not kinds_agree(schema, r.classes, r.ifc_class, state):
            continue
        rules = ctx.rules.of(state.ifc_types)
        if iri in ctx.used:  # matched once: only a partial view may name it again
            full = sizes_agree(rules, pose, held)
        else:
            score = matches(rules, pose, held)
            full = score > 0.0 and sizes_agree(rules, pose, held)
            if full and score > best_score:
                best, best_score = iri, score
        if not full and (
            heights_overlap(pose, held)
            and lies_within(pose, held, margin_m=rules.confirm_distance_m)
            and iou(pose, held) > within_score
        ):
            within, within_score = iri, iou(pose, held)
    if best is not None:
        return Association(target=best)
    return Association(within=within)


def adopt(ctx: FusionContext, r: ElementReport, match: str) -> ElementReport:
    """``r`` is ``match``: its IRI becomes an alias of it (if not already); returns the report without
    its class (the element has one)."""
    if r.iri != match:
        ctx.out.resolved[r.iri] = match
        if r.iri in ctx.memory.tentative:  # held, and now another robot's element: no longer new
            ctx.out.effects.append(count_tentative(r.iri, None))
        known = ctx.memory.aliases.get(r.iri)
        if known is None or known.target != match:
            ctx.out.aliases[r.iri] = match
            ctx.out.effects.append(set_alias(r.iri, match, ctx.arrival_ns))
    return replace(r, ifc_class=None, classes=())


def new_element(
    ctx: FusionContext,
    r: ElementReport,
    *,
    alias: Alias | None,
    target: str,
    known: bool,
    pose: Pose | None,
    storey: str | None,
    sense: int,
) -> None:
    """``r`` resolved to nothing the twin holds: an element of its own (``known``: the IRI names an
    element, removed), created now or held tentative. An alias to a removed element is dropped."""
    out = ctx.out
    if alias is not None and target != r.iri:
        out.effects.append(drop_alias(r.iri))
        out.unaliased.append(r.iri)
        out.resolved.pop(r.iri, None)
        target = r.iri
    admitted = held_back(ctx, r, pose=pose, storey=storey)
    if admitted.held:
        return  # held tentative until seen often enough (twin.fusion.tentative)
    if admitted.pose is not None and storey is not None:  # the mean of its held sightings
        pose = admitted.pose
        r = replace(r, box=box_of(pose, ctx.live.site.storeys[storey].elevation_m))
    if r.distinct:
        out.effects.append(mark_distinct(r.iri))
    ctx.reports.append(replace(r, iri=target))
    out.sense[target] = sense
    ctx.detected.add(target)
    out.effects.append(sighting(target, ctx.robot, sense))
    if pose is not None and storey is not None and not known:
        out.effects.append(confirmed_by(target, {ctx.robot: sense}))  # its creator sees it there
        ctx.pend(target, storey, pose, r=r)


def seen_within(ctx: FusionContext, r: ElementReport, element: str, sense: int) -> None:
    """``r`` is a partly hidden view of ``element``: it confirms the element is there (a sighting: no
    miss, no move, no new element, no alias). The element is not matched by it: a full report of it in
    the same observation still resolves to it (a chair under a table and the table, in either order)."""
    ctx.out.resolved[r.iri] = element
    ctx.out.seen.append(element)
    ctx.out.effects.append(sighting(element, ctx.robot, sense))
    ctx.detected.add(element)
    ctx.out.notes.append(f"<{r.iri}> seen by {ctx.robot}: part of <{element}> (smaller, within it)")
    ctx.decide(element, f"partial view by {ctx.robot}: a smaller box within its footprint confirms it")
