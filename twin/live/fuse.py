"""Many robots, one twin: what an observation means once the twin's other sightings are counted.

Before an observation is planned (:mod:`twin.live.plan`), :func:`fuse` applies the rules of
docs/fusion.md to each element it describes, in the table's order, each rule a function under
:mod:`twin.fusion`:

1. **sense time** (:mod:`twin.fusion.clocks`): when the report was seen; a change seen before what the
   twin holds is stale;
2. **association** (:mod:`twin.fusion.associate`, gates in :mod:`twin.fusion.gates`): an alias resolves
   to its element; a robot IRI the twin does not know resolves to the element it matches;
3. **new elements** (:mod:`twin.fusion.tentative`): what resolves to nothing is created, or held
   tentative (a robot that streams views: until its next view sees it again);
4. **confirmation or move** (:mod:`twin.fusion.confirm`): a sighting near the held pose confirms it
   (nothing written), a short move waits for agreeing sightings, a long one is applied;
5. **merge** (:mod:`twin.fusion.merge`): a move onto another element of a compatible class merges them;
6. **absence** (:mod:`twin.fusion.absence`): the view's elements not described collect misses; enough
   misses remove them.

It returns the reports to plan, rewritten to the elements they resolved to, and the in-memory effects
(:mod:`twin.fusion.effects`), which the writer applies only once the plan is accepted.

Example::

    fused = fuse(observation, robot="robot2", rights=rights, live=live, states=states, shapes=shapes,
                 pending={}, rules=config.fusion, base_iri=base, arrival_ns=now, now_ns=now)
    plan = plan_observation(fused.reports, ..., sense_ns=fused.sense, reasons=fused.reasons)
    fused.apply(live.fusion)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from twin.config import FusionRules, Right
from twin.errors import ObservationError
from twin.fusion.absence import absence
from twin.fusion.associate import (
    adopt,
    alias_fits,
    associate,
    contested_aliases,
    drop_failed_alias,
    new_element,
    seen_within,
    through_alias,
)
from twin.fusion.bias import note_sighting, unbiased
from twin.fusion.clocks import note_stale, refuse_future, robot_clock, stale_change, stale_tombstone
from twin.fusion.confirm import (
    box_of,
    confirmation,
    confirms,
    disputed,
    hold,
    move,
    resizable,
    resize_evidence,
    unsure_move,
)
from twin.fusion.confirm_array import confirm_array
from twin.fusion.context import Fused, FusionContext, Pending, report_pose
from twin.fusion.dispute import covered, older_disagreement, still_covers, widen
from twin.fusion.effects import looked, sighting
from twin.fusion.footprints import Pose
from twin.fusion.gates import compatible, is_candidate
from twin.fusion.history import echo, late_news, seen_echo, seen_late
from twin.fusion.memory import Alias
from twin.fusion.merge import merge_or_move, unmerge
from twin.fusion.tentative import drop_unseen, streams
from twin.live.state import ElementState, LiveState, StoreyFrame
from twin.records import ElementReport, Observation, Shape


def fuse(
    obs: Observation,
    *,
    robot: str,
    rights: frozenset[Right],
    live: LiveState,
    states: Mapping[str, ElementState],
    shapes: Mapping[str, Shape | None],
    pending: Pending,
    rules: FusionRules,
    base_iri: str,
    arrival_ns: int,
    now_ns: int,
) -> Fused:
    """Resolve, classify and complete ``obs`` (see the module's docstring); ObservationError names a
    sense time too far in the future or an unknown view storey. ``pending`` (created and moved elements
    earlier in the batch) is updated with this observation's."""
    clock = robot_clock(live.fusion, robot, obs, arrival_ns=arrival_ns, rules=rules)
    refuse_future(obs, clock, now_ns=now_ns, rules=rules)
    view = obs.view
    sense = clock.sense(view.sense_ns if view is not None else None)
    if view is not None and view.storey not in live.site.storeys:
        known = ", ".join(sorted(live.site.storeys)) or "none"
        raise ObservationError(f"The view's storey {view.storey!r} is unknown; storeys: {known}.")
    ctx = FusionContext(
        robot, rights, live, states, shapes, rules, base_iri, pending, arrival_ns, max(clock.offset_ns, 0)
    )
    if view is not None and rules.enabled:
        ctx.streaming = streams(live.fusion, robot, sense_ns=sense, rules=rules)
        ctx.out.effects.append(looked(robot, sense))
    senses = [clock.sense(r.sense_ns) if r.sense_ns is not None else sense for r in obs.reports]
    # the common case: confirmations at once (never of an observation that names an element twice, so
    # nothing is contested then)
    if not confirm_array(ctx, obs.reports, senses):
        if rules.enabled:
            ctx.contested = contested_aliases(ctx, obs.reports)  # one element, one object per observation
        for r, s in zip(obs.reports, senses, strict=True):
            _fuse_report(ctx, r, s)
    if view is not None and rules.enabled and live.fusion.tentative:  # held new objects not seen again
        drop_unseen(ctx, view, reported={r.iri for r in obs.reports})
    if view is not None and rules.enabled and "dynamic" in rights:
        absence(ctx, view=view, sense=sense)
    ctx.out.reports = tuple(ctx.reports)
    return ctx.out


def _fuse_report(ctx: FusionContext, r: ElementReport, sense: int) -> None:
    """One report, through the rules in the table's order."""
    if r.unmerge:
        unmerge(ctx, r, sense)
        return
    target, alias = through_alias(ctx, r)
    state = ctx.states.get(target)
    storey_key = r.storey or (state.storey if state is not None else None)
    storey = ctx.live.site.storeys.get(storey_key or "")
    raw = pose = report_pose(r, storey.elevation_m) if storey is not None else None
    if pose is not None and storey is not None and ctx.rules.enabled:
        pose = unbiased(ctx, pose)  # the robot's detector bias, once known
        if pose is not raw:
            r = replace(r, box=box_of(pose, storey.elevation_m))
    if _stale_sighting_of_removed(ctx, r, state, pose, sense):
        return
    if pose is not None and storey_key is not None:
        ctx.boxes.append((storey_key, r, pose))
    checked = _checked_alias(ctx, r, target, alias, state, pose, sense)
    if checked is None:
        return  # a partly hidden view of the element it names
    target, alias, state = checked
    exists = state is not None and not state.removed
    known = state is not None
    if not exists and ctx.rules.enabled and pose is not None and storey_key is not None and not r.distinct:
        found = associate(ctx, r, pose, storey_key)
        if found.target is not None:
            target, state, exists = found.target, ctx.states[found.target], True
            r = adopt(ctx, r, found.target)
        elif found.within is not None:
            seen_within(ctx, r, found.within, sense)  # a partly hidden view of it
            return
        elif not known and (late := late_news(ctx, r, pose, storey_key, sense)) is not None:
            seen_late(ctx, r, late, sense)  # seen before it moved or went: no ghost at the old place
            return
    if not exists or state is None:
        new_element(
            ctx, r, alias=alias, target=target, known=known, pose=pose, storey=storey_key, sense=sense
        )
        return
    _held_element(ctx, r, state, pose=pose, raw=raw, storey=storey, sense=sense)


def _stale_sighting_of_removed(
    ctx: FusionContext, r: ElementReport, state: ElementState | None, pose: Pose | None, sense: int
) -> bool:
    """A sighting of a removed element seen before its removal (noted stale), or its old place seen by
    a robot whose content may be older than its removal (late news: :func:`twin.fusion.history.echo`)."""
    if stale_tombstone(ctx, r, state, sense):
        return True
    if state is not None and state.removed and pose is not None and echo(ctx, state, pose, sense):
        seen_echo(ctx, r, state, sense)
        return True
    return False


def _checked_alias(  # noqa: PLR0917 (the report's state so far)
    ctx: FusionContext,
    r: ElementReport,
    target: str,
    alias: Alias | None,
    state: ElementState | None,
    pose: Pose | None,
    sense: int,
) -> tuple[str, Alias | None, ElementState | None] | None:
    """Whether an alias still names the element it resolved to (association's alias check): one that
    does not fit is dropped (associated afresh). An element's own IRI is trusted: a robot moves its
    element by it, as far as it likes (robots that reuse tracker ids scope them by session, as the ROS
    adapter does). Returns (target, alias, state), None when decided here."""
    if alias is None or state is None or state.removed or pose is None or not ctx.rules.enabled:
        return target, alias, state
    fit = "fails" if r.iri in ctx.contested else alias_fits(ctx, r, state, pose)  # checked, not trusted
    if fit == "within":
        seen_within(ctx, r, target, sense)  # a partly hidden view of it: no move
        return None
    if fit == "fails":
        drop_failed_alias(ctx, r, target)  # e.g. a reused tracker id: associated afresh
        return r.iri, None, ctx.states.get(r.iri)
    return target, alias, state


def _held_element(
    ctx: FusionContext,
    given: ElementReport,
    state: ElementState,
    *,
    pose: Pose | None,
    raw: Pose | None,
    storey: StoreyFrame | None,
    sense: int,
) -> None:
    """A report of an element the twin holds: stale, a confirmation, a held move, a move or a merge."""
    target = state.iri
    ctx.detected.add(target)
    ctx.used.add(target)
    r: ElementReport | None = given if given.iri == target else replace(given, iri=target)
    assert r is not None
    held = None
    if ctx.rules.enabled and pose is not None and storey is not None and is_candidate(state):
        held = ctx.held_pose(target)
    # seen before another robot's later sighting, a short move from where that robot saw it: a dispute
    older = held is not None and pose is not None and older_disagreement(ctx, r, state, pose, held, sense)
    if not older and stale_change(ctx, r, given.iri, state, sense):
        return
    ctx.out.effects.append(sighting(target, ctx.robot, sense, latest=not older))
    if raw is not None and ctx.rules.enabled and is_candidate(state) and not older:
        note_sighting(ctx, state, raw, sense)  # where this robot's detector puts it: its bias
    if held is not None and pose is not None and storey is not None:
        class_rules = ctx.rules.of(state.ifc_types)
        track = ctx.memory.tracks.get(target)
        covers = track is not None and still_covers(track.dispute, held)  # robots disagree: it covers both
        sizes = None if covers or older else resize_evidence(ctx, state, pose, held, sense)  # strong evidence
        confirmed = confirms(class_rules, pose, held, sizes=False)
        if not covers and not confirmed and echo(ctx, state, pose, sense):
            seen_echo(ctx, r, state, sense)  # back where it stood before its last move, seen late
            return
        if covers:
            r = covered(ctx, r, state, seen=pose, held=held, storey=storey, sense=sense)
        elif confirmed:
            r = confirmation(ctx, r, state, seen=pose, held=held, storey=storey, sense=sense, sizes=sizes)
        elif unsure_move(ctx, class_rules, pose, held, track=track, sense=sense):
            why = "a short move needs move_sightings agreeing sightings"  # an outlier is no move
            r = hold(ctx, r, state, seen=pose, held=held, storey=storey, sense=sense, sizes=sizes, why=why)
        elif dispute := disputed(ctx, state, pose, held, sense):
            if dispute == "tie" and sizes is None and resizable(ctx, target):  # it covers both poses
                r = widen(ctx, r, state, seen=pose, held=held, storey=storey, sense=sense)
            else:
                why = "more robots confirmed the held pose within disagreement_window_s"  # a bias
                r = hold(
                    ctx, r, state, seen=pose, held=held, storey=storey, sense=sense, sizes=sizes, why=why
                )
        elif older:  # an older report is never applied as a move
            note_stale(ctx, given.iri, state, sense)
            return
        else:
            r, pose = move(ctx, r, state, seen=pose, held=held, storey=storey, sense=sense, sizes=sizes)
            r = merge_or_move(ctx, r, state, pose, storey.key, sense=sense)
        if r is None:
            return  # a confirmation: nothing to plan
    if (
        r.ifc_class is not None
        and state.ifc_class.lower() != r.ifc_class.lower()
        and compatible(ctx.live.site.schema, r.ifc_class, state)
    ):
        r = replace(r, ifc_class=None)  # a robot's coarser or finer class for the same object
    ctx.reports.append(r)
    ctx.out.sense[r.iri] = sense
