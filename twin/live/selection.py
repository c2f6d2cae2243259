"""Skill selection for the elements an observation changed, evaluated in memory.

:func:`twin.skills.selection_query` is the definition of which elements a skill's maps are made of;
this module answers the same question from :class:`~twin.live.state.ElementState` without a query,
for every skill whose selection is made of types, classes and materials (every shipped one). A skill
with a custom ``sparql`` pattern cannot be answered from memory: :func:`needs_store` says so and the
writer asks the store for those.

Example::

    selects(skill, states[iri], has_geometry=shape is not None)      # True / False
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Mapping, Sequence

from twin.live.state import ElementState
from twin.skill_selection import VIRTUAL_TYPE, class_iri, selection_query
from twin.skills import SkillProfile
from twin.store import GraphStore


def needs_store(skill: SkillProfile) -> bool:
    """True when the skill's selection depends on more of the graph than the element's own state."""
    return skill.sparql is not None


@functools.cache
def _material_word(word: str) -> re.Pattern[str]:
    # Words are separated by anything but letters and digits, as twin.skills.material_word_pattern:
    # in Python's re, [\W_] is "not a letter or digit".
    return re.compile(rf"(?:^|[\W_]){re.escape(word)}(?:$|[\W_])", re.IGNORECASE)


def _has_type(state: ElementState, types: tuple[str, ...]) -> bool:
    for t in types:
        iri = class_iri(t)
        if (iri is not None and iri in state.classes) or (iri is None and t in state.ifc_types):
            return True
    return False


def _zone_fits(skill: SkillProfile, state: ElementState) -> bool:
    """Masks show their zones only; maps of the building never show virtual elements."""
    if skill.kind == "keepout":
        return state.keepout
    if skill.kind == "speed":
        return state.speed_limit == skill.limit_percent
    return VIRTUAL_TYPE not in state.ifc_types


def selects(skill: SkillProfile, state: ElementState, *, has_geometry: bool) -> bool:
    """Whether ``skill`` selects the element (what ``selection_query(skill)`` would answer).

    Raises ValueError for a skill with a custom ``sparql`` pattern (see :func:`needs_store`).
    """
    if needs_store(skill):
        msg = f"Skill {skill.name!r} has a SPARQL pattern: its selection needs the store."
        raise ValueError(msg)
    if state.removed or not has_geometry or state.is_open is True:
        return False
    if "https://w3id.org/bot#Element" not in state.classes or not _zone_fits(skill, state):
        return False
    if skill.include_types and not _has_type(state, skill.include_types):
        return False
    if skill.exclude_types and _has_type(state, skill.exclude_types):
        return False
    for word in skill.exclude_materials:
        pattern = _material_word(word)
        if any(pattern.search(m) for m in state.facing_materials):
            return False
    return True


def membership(
    store: GraphStore,
    skills: Mapping[str, SkillProfile],
    states: Mapping[str, ElementState],
    iris: Sequence[str],
    has_geometry: Callable[[str], bool],
) -> dict[str, dict[str, bool]]:
    """Per skill, whether it selects each of ``iris`` now: from memory (:func:`selects`), or from the
    store for a skill with its own SPARQL pattern. The one place the writer decides membership (after
    an observation, and when a restart replays what changed since the snapshot)."""
    out: dict[str, dict[str, bool]] = {}
    for name, skill in skills.items():
        if needs_store(skill):
            chosen = {r["element"] or "" for r in store.select(selection_query(skill, list(iris)))}
            out[name] = {i: i in chosen for i in iris}
        else:
            out[name] = {
                i: selects(skill, states[i], has_geometry=has_geometry(i)) for i in iris if i in states
            }
    return out
