"""Skill selection for the elements an observation changed, evaluated in memory.

:func:`twin.selection.skills.selection_query` is the definition of which elements a skill's maps are made of;
this module answers the same question from :class:`~twin.live.state.ElementState` without a query,
for every skill whose selection is made of types, classes and materials (every shipped one). A skill
with a custom ``sparql`` pattern cannot be answered from memory: :func:`needs_store` says so and the
writer asks the store for those.

Example::

    selects(skill, states[iri], has_geometry=shape is not None)      # True / False
    rejection(skill, states[iri], has_geometry=True)                 # None, or "excluded type IfcDoor"
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Mapping, Sequence

from twin.graph.store import GraphStore
from twin.live.state import ElementState
from twin.selection.skill_selection import VIRTUAL_TYPE, class_iri, selection_query
from twin.selection.skills import SkillProfile


def needs_store(skill: SkillProfile) -> bool:
    """True when the skill's selection depends on more of the graph than the element's own state."""
    return skill.sparql is not None


@functools.cache
def _material_word(word: str) -> re.Pattern[str]:
    # Words are separated by anything but letters and digits, as twin.selection.skills.material_word_pattern:
    # in Python's re, [\W_] is "not a letter or digit".
    return re.compile(rf"(?:^|[\W_]){re.escape(word)}(?:$|[\W_])", re.IGNORECASE)


def _first_type(state: ElementState, types: tuple[str, ...]) -> str | None:
    """The first of ``types`` the element has (an IFC name with subtypes, or a class), None if none."""
    for t in types:
        iri = class_iri(t)
        if (iri is not None and iri in state.classes) or (iri is None and t in state.ifc_types):
            return t
    return None


def _zone_misfit(skill: SkillProfile, state: ElementState) -> str | None:
    """Masks show their zones only; maps of the building never show virtual elements."""
    if skill.kind == "keepout":
        return None if state.keepout else "not marked as a keepout zone"
    if skill.kind == "speed":
        if state.speed_limit == skill.limit_percent:
            return None
        return f"not marked as a {skill.limit_percent} % speed zone"
    return "a virtual element (zones are in masks only)" if VIRTUAL_TYPE in state.ifc_types else None


def rejection(  # noqa: PLR0911 (one return per test, in the order their reasons are given)
    skill: SkillProfile, state: ElementState, *, has_geometry: bool
) -> str | None:
    """Why ``skill`` does not select the element, None when it does: the one rule, in memory, that
    ``selection_query(skill)`` states in SPARQL (:func:`selects` is this rule's yes or no, and
    ``twin explain`` gives its reasons).

    The first failing test names the reason: ``"removed"``, ``"no geometry"``, ``"a door observed
    open (passable)"``, ``"not a building element"``, a zone the element is not marked as, ``"a virtual
    element ..."``, ``"not among include_types [...]"``, ``"excluded type IfcX"``, ``"made of glass
    (Glass - Clear)"``. For a skill with a custom ``sparql`` pattern only the rest of its selection is
    judged: the pattern needs the store (:func:`needs_store`).
    """
    if state.removed:
        return "removed"
    if not has_geometry:
        return "no geometry"
    if state.is_open is True:
        return "a door observed open (passable)"
    if "https://w3id.org/bot#Element" not in state.classes:
        return "not a building element"
    if (misfit := _zone_misfit(skill, state)) is not None:
        return misfit
    if skill.include_types and _first_type(state, skill.include_types) is None:
        return f"not among include_types {list(skill.include_types)}"
    if skill.exclude_types and (t := _first_type(state, skill.exclude_types)) is not None:
        return f"excluded type {t}"
    for word in skill.exclude_materials:
        pattern = _material_word(word)
        faced = [m for m in sorted(state.facing_materials) if pattern.search(m)]
        if faced:
            return f"made of {word} ({faced[0]})"
    return None


def selects(skill: SkillProfile, state: ElementState, *, has_geometry: bool) -> bool:
    """Whether ``skill`` selects the element (what ``selection_query(skill)`` would answer): no
    :func:`rejection`.

    Raises ValueError for a skill with a custom ``sparql`` pattern (see :func:`needs_store`).
    """
    if needs_store(skill):
        msg = f"Skill {skill.name!r} has a SPARQL pattern: its selection needs the store."
        raise ValueError(msg)
    return rejection(skill, state, has_geometry=has_geometry) is None


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
