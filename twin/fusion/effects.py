"""Effects on fusion's memory: what a fused observation does to the sightings, misses, aliases and
held moves, applied by the writer only once the observation's plan is accepted (a refused observation
leaves the memory as it was).

Each function returns an :data:`~twin.fusion.context.Effect`, a closure over its values.

Example::

    fused.effects.append(sighting(iri, "robot1", sense_ns))
    fused.apply(live.fusion)
"""

from __future__ import annotations

from collections.abc import Callable

from twin.fusion.footprints import Pose
from twin.fusion.memory import Alias, Dispute, FusionMemory, Miss, Refinement, SizeEvidence, Tentative

Effect = Callable[[FusionMemory], None]


def sighting(iri: str, robot: str, sense: int, *, latest: bool = True) -> Effect:
    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        if latest:
            t.sighted(robot, sense)
        else:  # a stale sighting is counted, never taken as the latest
            seen = t.seen_ns
            t.sighted(robot, sense)
            t.seen_ns = seen

    return run


def miss(iri: str, robot: str, sense: int) -> Effect:
    return lambda m: m.track(iri).misses.append(Miss(robot, sense))


def forget(iri: str) -> Effect:
    def run(m: FusionMemory) -> None:
        t = m.existing(iri)
        if t is not None:
            t.misses.clear()
            t.refinement.n = 0

    return run


def refine(iri: str, pose: Pose, *, robot: str = "", sense: int = 0) -> Effect:
    """A confirmation by ``robot`` seen at ``sense``: averaged, and whatever seemed to move did not."""

    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        t.refinement.add(pose)
        t.moving = None
        t.movers.clear()
        if robot:
            t.confirmed[robot] = max(sense, t.confirmed.get(robot, sense))
            t.runs.pop(robot, None)  # this robot sees it where it is held: its own run ends

    return run


def hold_move(
    iri: str, pose: Pose, *, restart: bool, robot: str = "", restart_run: bool = True, sense: int = 0
) -> Effect:
    """Another sighting of a move not yet believed (by ``robot``): added to those it agrees with, or a
    new start; and to the robot's own run (``restart_run``: a new one)."""

    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        if robot:
            own = t.runs.get(robot)
            ref = Refinement() if restart_run or own is None else own[0].copy()
            ref.add(pose)
            t.runs[robot] = (ref, max(sense, own[1] if own is not None and not restart_run else 0))
        moving = t.moving
        if restart or moving is None:
            moving = Refinement()
            t.movers.clear()
        moving.add(pose)
        t.moving = moving
        if robot:
            t.movers.add(robot)
            t.confirmed.pop(robot, None)

    return run


def reset_refinement(iri: str) -> Effect:
    """A new pose committed: the confirmations, held moves and any dispute start again."""

    def run(m: FusionMemory) -> None:
        t = m.existing(iri)
        if t is not None:
            t.refinement = Refinement()
            t.moving = None
            t.movers.clear()
            t.confirmed.clear()
            t.runs.clear()
            t.dispute = None

    return run


def set_alias(alias: str, target: str, now: int) -> Effect:
    def run(m: FusionMemory) -> None:
        m.changing("aliases", alias)
        m.aliases[alias] = Alias(target, now)

    return run


def use_alias(alias: str, now: int) -> Effect:
    def run(m: FusionMemory) -> None:
        m.changing("aliases", alias)
        a = m.aliases.get(alias)
        if a is not None:
            a.used_ns = max(a.used_ns, now)

    return run


def drop_alias(alias: str) -> Effect:
    def run(m: FusionMemory) -> None:
        m.changing("aliases", alias)
        m.aliases.pop(alias, None)

    return run


def count_tentative(iri: str, seen: Tentative | None) -> Effect:
    """``iri`` held tentative as ``seen`` (None: no longer: created, resolved or dropped)."""

    def run(m: FusionMemory) -> None:
        m.changing("tentative", iri)
        if seen is not None:
            m.tentative[iri] = seen
        else:
            m.tentative.pop(iri, None)

    return run


def looked(robot: str, sense_ns: int) -> Effect:
    """``robot`` sent a view seen at ``sense_ns`` (a robot whose views come often streams)."""

    def run(m: FusionMemory) -> None:
        m.changing("views", robot)
        m.views[robot] = max(sense_ns, m.views.get(robot, sense_ns))

    return run


def mark_distinct(iri: str) -> Effect:
    def run(m: FusionMemory) -> None:
        m.changing("distinct", iri)
        m.distinct.add(iri)

    return run


def size_evidence(iri: str, robot: str | None, evidence: SizeEvidence | None) -> Effect:
    """Keep ``robot``'s evidence of other sizes (None: forget it; robot None: forget everyone's)."""

    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        if robot is None:
            t.sizes.clear()
        elif evidence is None:
            t.sizes.pop(robot, None)
        else:
            t.sizes[robot] = evidence

    return run


def decided(iri: str, rule: str) -> Effect:
    """Remember which rule decided the latest report of ``iri`` (shown by ``twin explain``)."""

    def run(m: FusionMemory) -> None:
        m.track(iri).decided = rule

    return run


def moved(iri: str) -> Effect:
    """The element moved: where robots put it (their means, :mod:`twin.fusion.bias`) starts again."""

    def run(m: FusionMemory) -> None:
        t = m.existing(iri)
        if t is not None:
            t.means.clear()

    return run


def disputed_poses(iri: str, dispute: Dispute | None) -> Effect:
    """Robots disagree on where ``iri`` stands: it covers ``dispute.poses`` (None: the dispute ended)."""

    def run(m: FusionMemory) -> None:
        m.track(iri).dispute = dispute

    return run


def took_side(iri: str, robot: str, side: int, sense: int) -> Effect:
    """``robot``'s latest sighting of a disputed element confirmed ``side``'s pose, the side it takes."""

    def run(m: FusionMemory) -> None:
        d = m.track(iri).dispute
        if d is not None:
            d.sides[robot] = (side, sense)
            d.leaning.pop(robot, None)

    return run


def leans(iri: str, robot: str, sightings: int) -> Effect:
    """``robot``'s latest ``sightings`` in a row of a disputed element confirmed the side it does not
    take (not yet enough to change sides)."""

    def run(m: FusionMemory) -> None:
        d = m.track(iri).dispute
        if d is not None:
            d.leaning[robot] = sightings

    return run


def confirmed_by(iri: str, robots: dict[str, int]) -> Effect:
    """``robots`` (-> the sense time) see ``iri`` where it now stands: the robot that created or moved it,
    the side that settled a dispute. Until their next sightings, another robot's short move waits for
    them as for any confirmation (a biased robot's two quick sightings do not move it first)."""

    def run(m: FusionMemory) -> None:
        t = m.track(iri)
        for robot, sense in robots.items():
            t.confirmed[robot] = max(sense, t.confirmed.get(robot, sense))

    return run
