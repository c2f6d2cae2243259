"""New elements: what resolves to nothing is created at once, or held until seen often enough.

Two rules hold a new object back (acked in ``"tentative"``, nothing written):

- ``tentative_sightings`` (1: off): every new robot IRI needs this many sightings (of that IRI).
- ``stream_sightings`` (2; 1: off), **M of N for a robot that streams views**: a robot whose previous
  view was seen within ``stream_gap_s`` of this one reports what it sees many times a second, and its
  view says where it looked. A new object it reports with a view is held until it is seen this many
  times in a row: its next view that should have seen the object
  (:func:`twin.fusion.visibility.view_sees`, as absence asks) and does not report it drops it, as a
  false detection. A false detection seen once is then never an element, so it is never created and
  removed again (two revisions, and maps to every robot, for nothing). A one-shot report
  (``twin observe``: no view, or the robot's first view in a while) creates at once. A held object
  reported again under another IRI (a detector without track ids gives each detection a one-off IRI)
  is found by place: its footprint overlaps and its size agrees, as association asks. It is created
  at the **mean of its sightings** (each aligned with the others': a flipped heading averages as the
  same yaw), as a short move is: a pose taken from one noisy sighting may be a map cell off, free floor
  inside the object until ``refine_after`` confirmations put it right, and a robot that glimpses an
  object a few times never sends them.

Example::

    streaming = streams(ctx.memory, "robot1", sense_ns=sense, rules=rules)   # the view's sense time
    admitted = held_back(ctx, r, pose=pose, storey="ground-floor")
    if admitted.held:
        return                       # acked in "tentative"
    pose = admitted.pose or pose     # the mean of its held sightings
    drop_unseen(ctx, view, reported={r.iri for r in obs.reports})
"""

from __future__ import annotations

from collections.abc import Set
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from twin.config import FusionRules
from twin.fusion.absence import VIEW_INSET_M
from twin.fusion.effects import count_tentative
from twin.fusion.footprints import Pose, aligned, box_pose
from twin.fusion.gates import matches, sizes_agree
from twin.fusion.memory import FusionMemory, Tentative
from twin.fusion.visibility import view_sees
from twin.records import ElementReport, ObservedView

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext


def streams(memory: FusionMemory, robot: str, *, sense_ns: int, rules: FusionRules) -> bool:
    """Whether ``robot``, sending a view seen at ``sense_ns`` (corrected), streams: its previous view was
    seen at most ``stream_gap_s`` before (or after: a report overtaken on the way). Sense times, not
    arrivals: two detection arrays seen 11 s apart that arrive together are two one-shot reports."""
    last = memory.views.get(robot)
    return last is not None and abs(sense_ns - last) <= rules.stream_gap_ns


class Admission(NamedTuple):
    """What :func:`held_back` decided of a new object: held tentative, or created (at ``pose``, the mean
    of its held sightings and this one; None: where this report puts it)."""

    held: bool
    pose: Pose | None = None


CREATED = Admission(held=False)


def held_back(ctx: FusionContext, r: ElementReport, *, pose: Pose | None, storey: str | None) -> Admission:
    """Whether the new object ``r`` (at ``pose`` on ``storey``) is held tentative rather than created
    now: its sightings so far (this one counted) are fewer than the rules ask; created, where (the mean
    of its sightings, once a robot that streams held it). Notes the effect either way (held: counted;
    created: no longer held)."""
    if r.box is None and r.geometry is None:
        return CREATED
    rules = ctx.rules
    needed = rules.tentative_sightings
    streamed = ctx.streaming and pose is not None and storey is not None
    if streamed:
        needed = max(needed, rules.stream_sightings)
    known = ctx.memory.tentative.get(r.iri)
    if needed <= 1:
        if known is not None:
            ctx.out.effects.append(count_tentative(r.iri, None))
        return CREATED
    if known is None and streamed and rules.stream_sightings > 1 and pose is not None:
        before = same_place(ctx, pose, storey or "")  # a new IRI for it (a detector without track ids)
        if before is not None:
            known = ctx.memory.tentative[before]
            ctx.held_seen.add(before)
            ctx.out.effects.append(count_tentative(before, None))  # counted on under the new IRI
    seen = (known.seen if known is not None else 0) + 1
    mean = pose
    if streamed and pose is not None and known is not None and known.pose is not None:
        mean = running_mean(known.pose, known.seen, pose)
    if seen >= needed:
        ctx.out.effects.append(count_tentative(r.iri, None))
        return Admission(held=False, pose=mean if mean is not pose else None)
    since = known.since_ns if known is not None else ctx.arrival_ns
    held = Tentative(seen, since, ctx.robot, storey or "", mean) if streamed else Tentative(seen, since)
    ctx.out.tentative.append(r.iri)
    ctx.out.effects.append(count_tentative(r.iri, held))
    return Admission(held=True)


def running_mean(mean: Pose, n: int, pose: Pose) -> Pose:
    """The mean of ``n`` sightings (``mean``) and one more, ``pose``, aligned with it first (a flipped
    heading or a quarter turn of a square footprint averages as the same yaw)."""
    a = aligned(pose, mean)
    k = n + 1
    return box_pose(
        (mean.cx * n + a.cx) / k,
        (mean.cy * n + a.cy) / k,
        (mean.cz * n + a.cz) / k,
        (mean.sx * n + a.sx) / k,
        (mean.sy * n + a.sy) / k,
        (mean.sz * n + a.sz) / k,
        yaw=(mean.yaw * n + a.yaw) / k,
    )


def same_place(ctx: FusionContext, pose: Pose, storey: str) -> str | None:
    """The object this robot holds from its earlier views on ``storey`` that ``pose`` is, by place: their
    footprints overlap and their sizes agree, as association asks (the best match), not matched yet."""
    best, best_score = None, 0.0
    rules = ctx.rules.default
    for iri, t in ctx.memory.tentative.items():
        if t.pose is None or t.robot != ctx.robot or t.storey != storey or iri in ctx.held_seen:
            continue
        score = matches(rules, pose, t.pose)
        if score > best_score and sizes_agree(rules, pose, t.pose):
            best, best_score = iri, score
    return best


def drop_unseen(ctx: FusionContext, view: ObservedView, *, reported: Set[str]) -> None:
    """Drop the objects this robot holds from its earlier views that ``view`` should have seen and the
    observation does not report (``reported``: its IRIs): false detections, seen once."""
    memory = ctx.memory
    if not memory.tentative:
        return
    mine = [
        (iri, t.pose)
        for iri, t in memory.tentative.items()
        if t.pose is not None
        and t.robot == ctx.robot
        and t.storey == view.storey
        and iri not in reported
        and iri not in ctx.held_seen
    ]
    if not mine:
        return
    ring = np.concatenate(view.polygons)
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    if view.origin is not None:
        lo, hi = np.minimum(lo, view.origin[:2]), np.maximum(hi, view.origin[:2])
    seen = view_sees(
        view,
        [pose for _, pose in mine],
        iris=[iri for iri, _ in mine],
        held=ctx.candidates_near(view.storey, lo, hi),
        sightings=[box for _, _, box in ctx.boxes],
        elevation_m=ctx.live.site.storeys[view.storey].elevation_m,
        inset_m=VIEW_INSET_M,
    )
    for (iri, _), should in zip(mine, seen, strict=True):
        if should:
            ctx.out.effects.append(count_tentative(iri, None))
            ctx.out.notes.append(f"<{iri}> dropped: {ctx.robot}'s next view should have seen it and did not")
