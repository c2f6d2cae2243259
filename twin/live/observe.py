"""The hot path: a batch of robot observations, from payload to acks.

For each observation, in order: parse it (an identical payload is parsed once: robots re-send the same
bytes), plan it against the twin as the observations before it in the batch left it
(:func:`~twin.live.plan.plan_observation`), and answer at once when it is invalid or changes nothing
(a re-confirmation: ``"unchanged": true``, no revision). The observations that change something are
committed together in one store transaction (group commit: each keeps its own revision and its changes
apply in order), then the maps are brought up to date once for all of them and each is acked with its
revision and the map rectangles that changed. An ack always follows the commit.

Fusion's effects on its memory (:mod:`twin.fusion.effects`) apply as each observation is planned, so that
the batch's next observations see them; from the first observation that changes something they are
journaled (:meth:`~twin.fusion.memory.FusionMemory.begin`), and a commit the store refuses (a full disk)
undoes them: the memory is as it was before that observation (the unchanged observations acked after it
in the batch leave no trace either), and only the robots' clock offsets, facts of the transport, stay.

Skill selection of the changed elements is answered from memory (:mod:`twin.live.membership`); only a
skill with its own SPARQL pattern asks the store.

Example::

    observer = Observer(store, config, live, emit=sinks.emit, clock=time.time_ns)
    observer.observe_batch([ObserveRequest("robot1", payload, reply, time.time_ns())])
"""

from __future__ import annotations

import logging
from collections import Counter, OrderedDict, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from twin.config import Config
from twin.errors import TwinError
from twin.fusion.context import Fused
from twin.fusion.footprints import Pose
from twin.fusion.gates import is_candidate
from twin.fusion.memory import FusionMemory, expire_aliases
from twin.fusion.poses import index_element
from twin.graph import vocab
from twin.graph.rdf import ChangeSet, Object, Triple
from twin.graph.store import GraphStore
from twin.live.events import (
    ElementShape,
    MapChange,
    MapUpdated,
    ObservationAccepted,
    ObservationNoted,
    ObservationRejected,
    TwinEvent,
)
from twin.live.fuse import fuse
from twin.live.layered import Layered
from twin.live.membership import membership
from twin.live.parse import parse_observation_document
from twin.live.plan import ObservationPlan, plan_observation
from twin.live.publication import Publication
from twin.live.requests import ObserveRequest, Reply
from twin.live.state import ElementState, LiveState, Sighting
from twin.live.tombstones import FORGET_BATCH, due_tombstones, forget_changes, forget_elements, still_due
from twin.live.validate import check_observation
from twin.records import ElementReport, GeometryChange, Observation, Shape

log = logging.getLogger(__name__)

_PARSED_CACHE = 1024  # distinct payloads whose parse is remembered (robots re-send the same bytes)


@dataclass(frozen=True, eq=False, slots=True)
class _Planned:
    request: ObserveRequest
    plan: ObservationPlan
    revision: int
    fused: Fused


def element_shapes(live: LiveState, iris: Sequence[str]) -> tuple[ElementShape, ...]:
    """The current shape of the given elements (those with geometry)."""
    out = []
    for iri in iris:
        shape = live.maps.shape_of(iri)
        state = live.states.get(iri)
        if shape is None or state is None:
            continue
        out.append(
            ElementShape(
                iri=iri,
                ifc_class=state.ifc_class,
                name=state.name,
                storey=state.storey,
                mesh=shape[0],
                placement=shape[1],
                is_static=state.is_static,
                is_open=state.is_open,
            )
        )
    return tuple(out)


class Observer:
    """Turns batches of observations into one commit, one map pass and their acks (the writer's job)."""

    def __init__(
        self,
        store: GraphStore,
        config: Config,
        live: LiveState,
        *,
        emit: Callable[[TwinEvent], None],
        send: Callable[[ObserveRequest, Reply], None],
        clock: Callable[[], int],
        publication: Publication,
        base_iri: str = "",
    ) -> None:
        self.store = store
        self.config = config
        self.live = live
        self.emit = emit
        self.send = send
        self.clock = clock
        self.accepted = 0
        self.unchanged = 0
        self.rejected = 0
        self.publication = publication
        self.stale = 0
        self.fusion_counts: Counter[str] = Counter()
        """What fusion decided, counted: resolved IRIs, confirmations, refined poses, merges, removals
        by absence, creations and moves (the last four of committed observations)."""
        self.base_iri = base_iri
        self._parsed: OrderedDict[bytes, Observation] = OrderedDict()
        self._due: deque[str] = deque()  # tombstones found due, oldest first, not forgotten yet

    def _parse(self, payload: bytes) -> Observation:
        parsed = self._parsed.get(payload)
        if parsed is None:
            parsed = parse_observation_document(payload, limits=self.config.limits)
            self._parsed[payload] = parsed
            if len(self._parsed) > _PARSED_CACHE:
                self._parsed.popitem(last=False)
        else:
            self._parsed.move_to_end(payload)
        return parsed

    def _reject(self, req: ObserveRequest, err: TwinError) -> None:
        self.rejected += 1
        log.warning("Rejected an observation by %s: %s", req.robot, err)
        self.emit(ObservationRejected(req.robot, str(err), self.clock(), len(req.payload)))
        self.send(req, Reply.error(str(err)))

    def observe_batch(self, batch: Sequence[ObserveRequest]) -> None:
        """Handle ``batch`` in order; every request gets its reply through ``send``."""
        live = self.live
        states: dict[str, ElementState] = {}  # what this batch changed, not yet committed
        shapes: dict[str, Shape | None] = {}
        held: dict[str, dict[str, Object | None]] = {}
        pending: dict[str, tuple[str, Pose, ElementState]] = {}
        planned: list[_Planned] = []
        aliases: dict[str, str | None] = {}  # robot IRI -> element (None: forget it), to write
        now = self.clock()
        for req in batch:
            try:
                obs = req.observation
                if obs is None:
                    obs = self._parse(req.payload)
                elif not req.checked:
                    check_observation(obs, limits=self.config.limits)
                current = Layered(states, live.states) if states else live.states
                fused = fuse(
                    obs,
                    robot=req.robot,
                    rights=self.config.rights_of(req.robot),
                    live=live,
                    states=current,
                    shapes=shapes,
                    pending=dict(pending),
                    rules=self.config.fusion,
                    base_iri=self.base_iri,
                    arrival_ns=req.received_ns,
                    now_ns=now,
                )
                reports = fused.reports
                plan = plan_observation(
                    reports,
                    robot=req.robot,
                    rights=self.config.rights_of(req.robot),
                    site=live.site,
                    states=current,
                    shapes={
                        r.iri: shapes[r.iri] if r.iri in shapes else live.maps.shape_of(r.iri)
                        for r in reports
                    },
                    held=Layered(held, live.held),  # (not Layered[...](): a generic alias costs a call)
                    revision=live.revision + len(planned) + 1,
                    stamp_ns=req.received_ns,
                    sense_ns=fused.sense,
                    reasons=fused.reasons,
                    merged=fused.merged,
                )
            except TwinError as err:  # ObservationError included
                self._reject(req, err)
                continue
            if not plan.unchanged:  # its effects stand once the store accepts it (undone if refused)
                live.fusion.begin()
            fused.apply(live.fusion)  # the batch's next observations see them
            aliases.update(fused.aliases)
            aliases.update((a, None) for a in fused.unaliased)
            self.stale += len(fused.stale)
            self.fusion_counts["resolved"] += len(fused.resolved)
            self.fusion_counts["confirmed"] += len(fused.seen)
            sighting = Sighting(req.robot, req.received_ns)  # one for all (never changed in place)
            for iri in (*(r.iri for r in reports), *fused.seen):
                live.last_seen[iri] = sighting
            if plan.unchanged:
                self.unchanged += 1
                if fused.notes:
                    self.emit(
                        ObservationNoted(
                            req.robot, live.revision + len(planned), self.clock(), tuple(fused.notes)
                        )
                    )
                self.send(
                    req,
                    Reply(
                        True,
                        {
                            "ok": True,
                            "revision": live.revision + len(planned),
                            "unchanged": True,
                            "upserted": [],
                            "removed": [],
                            "maps": [],
                            **fused.ack(),
                        },
                    ),
                )
                continue
            states.update(plan.states)
            shapes.update((g.iri, g.new) for g in plan.geometry)
            pending.update(fused_pending(fused, plan, states, live.fusion))
            for subject, values in plan.written.items():
                base = {} if subject in plan.cleared else dict(held.get(subject, live.held.get(subject, {})))
                held[subject] = base | values
            planned.append(_Planned(req, plan, live.revision + len(planned) + 1, fused))
        alias_changes = _alias_changes(aliases)
        if planned:
            self._commit(planned, states, shapes, held, alias_changes)
        elif alias_changes:
            try:
                self.store.apply(alias_changes)
            except TwinError as err:  # an alias is found again at the next sighting
                log.warning("Could not write %d aliases: %s", len(aliases), err)

    def expire_aliases(self) -> int:
        """Forget the aliases unused for ``[fusion] alias_ttl_s`` (memory and graph); returns how many."""
        old = expire_aliases(self.live.fusion, self.clock(), self.config.fusion.alias_ttl_ns)
        if old:
            changes = _alias_changes(dict.fromkeys(old))
            try:
                if changes is not None:
                    self.store.apply(changes)
            except TwinError as err:
                log.warning("Could not forget %d aliases: %s", len(old), err)
        return len(old)

    def forget_tombstones(self, *, limit: int = FORGET_BATCH) -> int:
        """Forget the removed elements whose removal was sensed more than ``[fusion] tombstone_ttl_s``
        ago (at most ``limit``, oldest first; see :mod:`twin.live.tombstones`): their triples in one
        store transaction, then everything the writer holds of them. Returns how many (a store that
        refuses keeps them all, for the next pass)."""
        live, now, ttl = self.live, self.clock(), self.config.fusion.tombstone_ttl_ns
        if not self._due:  # one walk of the states, worked off over the next passes
            self._due.extend(due_tombstones(live, now_ns=now, ttl_ns=ttl, base_iri=self.base_iri))
        due: list[str] = []
        while self._due and len(due) < limit:
            iri = self._due.popleft()
            if still_due(live, iri, now_ns=now, ttl_ns=ttl):
                due.append(iri)
        if not due:
            return 0
        try:
            self.store.apply(forget_changes(self.store, live, due))
        except TwinError as err:
            log.warning("Could not forget %d removed elements: %s", len(due), err)
            self._due.extendleft(reversed(due))
            return 0
        forget_elements(live, due)
        self.fusion_counts["forgotten"] += len(due)
        log.debug("Forgot %d removed elements (oldest <%s>)", len(due), due[0])
        return len(due)

    def expire_unconfirmed(self) -> list[str]:
        """Remove the robot-added elements nobody has seen for their class's ``[fusion] ttl_s`` (off
        unless set): one commit, by ``fusion``, each with its reason. Returns their IRIs."""
        live, rules, now = self.live, self.config.fusion, self.clock()
        if not rules.enabled or (
            rules.default.ttl_ns <= 0 and not any(r.ttl_ns > 0 for r in (rules.per_class or {}).values())
        ):
            return []
        reasons: dict[str, str] = {}
        for iri, state in live.states.items():
            if iri.startswith(self.base_iri) or not is_candidate(state):
                continue  # imported elements and zones never expire
            ttl = rules.of(state.ifc_types).ttl_ns
            track = live.fusion.tracks.get(iri)
            seen = max(state.sensed_ns, track.seen_ns if track is not None else 0)
            if ttl > 0 and seen and now - seen > ttl:
                reasons[iri] = f"expired: nobody saw it for {ttl / 1e9:g} s (last {seen / 1e9:.3f})"
        if not reasons:
            return []
        reports = tuple(ElementReport(iri, removed=True) for iri in sorted(reasons))
        revision = live.revision + 1
        plan = plan_observation(
            reports,
            robot="fusion",
            rights=frozenset({"dynamic", "static"}),
            site=live.site,
            states=live.states,
            shapes={r.iri: live.maps.shape_of(r.iri) for r in reports},
            held=live.held,
            revision=revision,
            stamp_ns=now,
            reasons=reasons,
        )
        request = ObserveRequest("fusion", b"", None, now)
        fused = Fused(
            reports=reports, reasons=reasons, notes=[f"<{i}> removed: {w}" for i, w in reasons.items()]
        )
        held = {s: dict(v) for s, v in plan.written.items()}
        shapes = {g.iri: g.new for g in plan.geometry}
        self._commit([_Planned(request, plan, revision, fused)], dict(plan.states), shapes, held)
        return sorted(reasons)

    def _commit(
        self,
        planned: list[_Planned],
        states: dict[str, ElementState],
        shapes: dict[str, Shape | None],
        held: dict[str, dict[str, Object | None]],
        alias_changes: ChangeSet | None = None,
    ) -> None:
        live = self.live
        try:
            extra = (alias_changes,) if alias_changes else ()
            self.store.apply(*(p.plan.changes for p in planned), *extra)  # durable from here on
        except TwinError as err:
            log.error("The store refused a commit of %d observations: %s", len(planned), err)
            live.fusion.undo()  # fusion's memory as before the first of them
            for p in planned:
                self._reject(p.request, err)
            return
        live.fusion.keep()
        live.advance(planned[-1].revision)
        for p in planned:
            self.fusion_counts["refined"] += len(p.fused.refined)
            self.fusion_counts["merged"] += len(p.fused.merged)
            self.fusion_counts["removed_absent"] += sum(
                w.startswith("absent") for w in p.fused.reasons.values()
            )
            self.fusion_counts["removed_expired"] += sum(
                w.startswith("expired") for w in p.fused.reasons.values()
            )
            self.fusion_counts["created"] += sum(1 for i in p.plan.upserted if i not in live.states)
            self.fusion_counts["changed"] += sum(1 for i in p.plan.upserted if i in live.states)
        live.states.update(states)
        live.held.update(held)
        self.accepted += len(planned)
        stamp = self.clock()
        geometry: list[GeometryChange] = [g for p in planned for g in p.plan.geometry]
        membership = self._membership(list(states), shapes)
        changes = []
        for u in live.maps.redraw(geometry, membership):
            m = live.maps.skill_maps[(u.storey, u.skill)]
            self.emit(
                MapUpdated(u.storey, u.skill, m.plan.frame, u.window, u.data, live.revision, u.version, stamp)
            )
            self.publication.changed((u.storey, u.skill), stamp)
            changes.append(MapChange(u.storey, u.skill, u.version, u.window))
        for iri in states:  # after the redraw: the poses are those of the shapes the maps now show
            index_element(live, iri, live.states[iri])
            if live.states[iri].removed:  # its tombstone keeps the removal's sense time
                live.fusion.tracks.pop(iri, None)
        maps = tuple(changes)
        as_json = [c.as_json() for c in maps]
        for p in planned:
            self.emit(
                ObservationAccepted(
                    robot=p.request.robot,
                    revision=p.revision,
                    stamp_ns=stamp,
                    upserted=element_shapes(live, p.plan.upserted),
                    removed=p.plan.removed,
                    maps=maps,
                    notes=tuple(p.fused.notes),
                )
            )
            body: dict[str, object] = {
                "ok": True,
                "revision": p.revision,
                "upserted": list(p.plan.upserted),
                "removed": list(p.plan.removed),
                "maps": as_json,
                **p.fused.ack(),
            }
            self.send(p.request, Reply(True, body))

    def _membership(self, iris: list[str], shapes: dict[str, Shape | None]) -> dict[str, dict[str, bool]]:
        """Per skill, whether it now selects each changed element."""
        live = self.live

        def has_geometry(i: str) -> bool:
            return (shapes[i] is not None) if i in shapes else live.maps.shape_of(i) is not None

        return membership(self.store, live.skills, live.states, iris, has_geometry)


def fused_pending(
    fused: Fused, plan: ObservationPlan, states: dict[str, ElementState], memory: FusionMemory
) -> dict[str, tuple[str, Pose, ElementState]]:
    """The poses this observation gave elements, for the next observations of the batch to match
    (through ``memory``'s cache of poses: the commit indexes the same shapes)."""
    out = {}
    for g in plan.geometry:
        state = states.get(g.iri)
        if g.new is None or state is None or state.storey is None:
            continue
        out[g.iri] = (state.storey, memory.pose(g.iri, g.new), state)
    return out


def _alias_changes(aliases: dict[str, str | None]) -> ChangeSet | None:
    if not aliases:
        return None
    return ChangeSet(
        remove=tuple((a, vocab.TWIN_ALIAS_OF) for a in sorted(aliases)),
        add=tuple(Triple(a, vocab.TWIN_ALIAS_OF, t) for a, t in sorted(aliases.items()) if t is not None),
    )
