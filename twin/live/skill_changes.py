"""Skill profiles added, replaced or removed while the daemon runs, kept in the graph.

A change is one store transaction (the profile's JSON on a ``twin:Skill`` node, or its removal mark),
then the skill's maps are dropped and, for an added or replaced profile, built anew.

Example::

    reply = change_skill(store, live, base_iri, "tall", b'{"kind": "navigation", "robot_height_m": 2}')
"""

from __future__ import annotations

import json
import logging

from twin import vocab
from twin.errors import SkillError
from twin.live.live_maps import LiveMap
from twin.live.state import LiveState
from twin.skills import SkillProfile, parse_skill_json, selection_query
from twin.store import ChangeSet, GraphStore, RdfLiteral, Triple

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
    """Build the skill's map of every storey (its selection asked of the store once)."""
    selected = {r["element"] or "" for r in store.select(selection_query(skill))}
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
