"""Skill profiles added, replaced or removed while the daemon runs, kept in the graph.

A change is one store transaction (the profile's JSON on a ``twin:Skill`` node, or its removal mark),
then the skill's maps are dropped and, for an added or replaced profile, built anew.

Example::

    reply = apply_skill(store, live, SkillRequest("tall", b'{"kind": "navigation", "robot_height_m": 2}'),
                        base_iri=base_iri, publication=publication, emit=sink.emit, stamp=time.time_ns())
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable

from twin.errors import SkillError, TwinError
from twin.graph import vocab
from twin.graph.rdf import ChangeSet, RdfLiteral, Triple
from twin.graph.store import GraphStore
from twin.live.events import MapRemoved, SkillChanged, TwinEvent
from twin.live.live_map import LiveMap
from twin.live.publication import Publication
from twin.live.requests import Reply, SkillRequest
from twin.live.snapshots import Restored
from twin.live.state import LiveState
from twin.selection.skill_selection import selection_query
from twin.selection.skills import SkillProfile, parse_skill_json

log = logging.getLogger(__name__)


def stored_skills(store: GraphStore, configured: dict[str, SkillProfile]) -> dict[str, SkillProfile]:
    """The configured skills with those added (or removed) at run time applied, as the graph keeps them."""
    out = dict(configured)
    rows = store.select(
        "SELECT ?name ?json ?gone WHERE { ?s a twin:Skill ; rdfs:label ?name . "
        "OPTIONAL { ?s twin:profileJson ?json } OPTIONAL { ?s twin:removed ?gone } }"
    )
    for r in rows:
        name = r["name"] or ""
        if r["gone"] in ("true", "1"):
            out.pop(name, None)
            continue
        try:
            out[name] = parse_skill_json(name, r["json"] or "")
        except SkillError as err:
            log.warning("Ignoring the stored skill %r: %s", name, err)
    return out


def add_skill_maps(store: GraphStore, live: LiveState, skill: SkillProfile) -> list[LiveMap]:
    """Build the skill's map of every storey (its selection asked of the store once). A ``points``
    skill's clouds go to ``live.maps.points`` (no 2D map: the list is empty)."""
    selected = {r["element"] or "" for r in store.select(selection_query(skill))}
    if skill.kind == "points":
        live.maps.points.add_maps(skill, [s.key for s in live.maps.scene.storeys], selected)
        return []
    return [live.maps.add_map(skill, s.key, selected) for s in live.maps.scene.storeys]


def skill_change(
    base_iri: str, name: str, payload: bytes | None, live: LiveState
) -> tuple[ChangeSet, SkillProfile | None]:
    """The transaction that adds/replaces (``payload``: JSON) or removes (None) skill ``name``;
    SkillError names what is wrong (an unknown skill, a bad profile)."""
    node = vocab.skill_iri(base_iri, name)
    head = (Triple(node, vocab.RDF_TYPE, vocab.TWIN_SKILL), Triple(node, vocab.RDFS_LABEL, RdfLiteral(name)))
    if payload is None:
        if name not in live.skills:
            known = ", ".join(sorted(live.skills)) or "none"
            msg = f"Unknown skill {name!r}; skills: {known}."
            raise SkillError(msg)
        gone = Triple(node, vocab.TWIN_REMOVED, RdfLiteral("true", vocab.XSD_BOOLEAN))
        return ChangeSet(remove=((node, None),), add=(*head, gone)), None
    profile = parse_skill_json(name, payload)
    body = Triple(node, vocab.TWIN_PROFILE_JSON, RdfLiteral(json.dumps(profile.to_json())))
    return ChangeSet(remove=((node, None),), add=(*head, body)), profile


def apply_skill(
    store: GraphStore,
    live: LiveState,
    req: SkillRequest,
    *,
    base_iri: str,
    publication: Publication,
    emit: Callable[[TwinEvent], None],
    stamp: int,
) -> Reply:
    """Commit the skill change ``req``, drop the skill's old maps, build and publish its new ones."""
    try:
        changes, profile = skill_change(base_iri, req.name, req.payload, live)
        store.apply(changes)
    except TwinError as err:
        log.info("Refused a skill change for %r: %s", req.name, err)
        return Reply.error(str(err))
    live.advance(live.revision + 1)
    for storey, skill in live.maps.remove_skill(req.name):
        publication.drop((storey, skill))
        emit(MapRemoved(storey, skill, live.revision, stamp))
    if profile is None:
        del live.skills[req.name]
    else:
        live.skills[req.name] = profile
    emit(SkillChanged(req.name, profile, live.revision, stamp))
    maps = add_skill_maps(store, live, profile) if profile is not None else []
    for m in maps:
        publication.publish(m, live.revision, stamp)
    return Reply(
        True,
        {
            "ok": True,
            "revision": live.revision,
            "skill": req.name,
            "removed": profile is None,
            "maps": [{"storey": m.plan.storey.key, "skill": req.name, "version": m.version} for m in maps],
        },
    )


def publish_all_maps(
    store: GraphStore, live: LiveState, publication: Publication, restored: Restored | None, stamp: int
) -> Restored | None:
    """Publish every skill's map of every storey at start: those restored from a snapshot first, then
    the others built from the store. Returns the restored state whose triangles are still to be
    computed (before the first request), or None."""
    completing = None
    if restored is not None:  # the maps first, then the triangles they were drawn from
        for skill in live.skills.values():
            if skill.name in restored.skills and skill.kind != "points":  # clouds: PointsPublication
                for s in live.maps.scene.storeys:
                    publication.publish(live.maps.skill_maps[(s.key, skill.name)], live.revision, stamp)
        if not restored.skills >= frozenset(live.skills):
            restored.complete()  # the other skills' maps are rendered now
        else:
            completing = restored
    for skill in live.skills.values():
        if restored is None or skill.name not in restored.skills:
            for m in add_skill_maps(store, live, skill):
                publication.publish(m, live.revision, stamp)
    return completing
