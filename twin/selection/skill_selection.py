"""The selection of a skill's elements: one SPARQL query over the graph.

A profile's ``include_types`` and ``exclude_types`` name IFC classes (their subtypes included, through
``twin:ifcType``) or BEO/FURN classes (a CURIE such as ``beo:Wall`` or an ``<IRI>``);
``exclude_materials`` drops an element when a material a sensor faces contains one of the words; a
raw ``sparql`` pattern on ``?element`` narrows the rest. Masks select the zones operators mark
(``twin:keepout``, ``twin:speedLimit``); other maps never select virtual elements.

Example::

    rows = store.select(selection_query(skill))
    rows = store.select(selection_query(skill, only=[iri]))   # is this one element in the map?
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING

from twin.graph import vocab

if TYPE_CHECKING:
    from twin.selection.skills import SkillProfile

VIRTUAL_TYPE = "IfcVirtualElement"
"""Virtual elements (e.g. a zone an operator drew) are in masks only."""
_IRI = re.compile(r'^[^<>"{}|^`\\\s]+:[^<>"{}|^`\\\s]*$')
_REGEX_SPECIAL = frozenset("\\.^$|?*+()[]{}")
_CURIE = re.compile(r"^(?P<prefix>[a-z]+):(?P<local>[A-Za-z0-9_-]+)$")


def class_iri(value: str) -> str | None:
    """The class IRI a CURIE (``beo:Wall``) or ``<IRI>`` names, None for anything else (an IFC name)."""
    m = _CURIE.match(value)
    if m and m["prefix"] in vocab.PREFIXES:
        return vocab.PREFIXES[m["prefix"]] + m["local"]
    if value.startswith("<") and value.endswith(">") and "://" in value and " " not in value:
        return value[1:-1]
    return None


def _type_test(types: tuple[str, ...]) -> str:
    """A pattern true when ?element has one of ``types`` (IFC names with subtypes, or class IRIs)."""
    alternatives = []
    for t in types:
        iri = class_iri(t)
        if iri is not None:
            alternatives.append(f"{{ ?element a <{iri}> }}")
        else:
            alternatives.append(f"{{ ?element twin:ifcType {json.dumps(t)} }}")
    return " UNION ".join(alternatives)


def material_word_pattern(word: str) -> str:
    """A regular expression matching material names that contain ``word`` as a whole word.

    Words are separated by anything but letters and digits ("Glass - Clear", "glazing_glass" contain
    the word "glass"; "Fiberglass Batt" does not). Match it case-insensitively.
    """
    escaped = "".join(f"\\{c}" if c in _REGEX_SPECIAL else c for c in word)
    return f"(^|[^\\p{{L}}\\p{{N}}]){escaped}($|[^\\p{{L}}\\p{{N}}])"


def selection_query(skill: SkillProfile, only: Sequence[str] | None = None) -> str:
    """The SPARQL SELECT of the ``?element`` IRIs the skill's maps are made of (with geometry only).

    The user's pattern runs as a sub-select that projects only ``?element``: its other variables can
    neither bind nor undo the type and material filters. ``exclude_materials`` drops an element when a
    material a sensor faces (``twin:facingMaterial``) contains one of the words, case-insensitively.
    Doors observed open (``twin:isOpen true``) are never selected: they are passable, and a sensor
    sees through their doorway. Removed elements (tombstones, ``twin:removed true``) are never selected.
    With ``only``, just those IRIs are tested (what the daemon does after
    a change: cheap on any graph).
    """
    lines = ["SELECT DISTINCT ?element WHERE {"]
    if only is not None:
        values = " ".join(f"<{iri}>" for iri in only if _IRI.match(iri))
        lines.append(f"  VALUES ?element {{ {values} }}")
    lines += [
        "  ?element a bot:Element ; omg:hasGeometry ?twin_geometry .",
        "  FILTER NOT EXISTS { ?element twin:isOpen true }",
        "  FILTER NOT EXISTS { ?element twin:removed true }",
    ]
    if skill.kind == "keepout":
        lines.append("  ?element twin:keepout true .")
    elif skill.kind == "speed":
        lines.append(f"  ?element twin:speedLimit {skill.limit_percent} .")
    else:
        lines.append(f'  FILTER NOT EXISTS {{ ?element twin:ifcType "{VIRTUAL_TYPE}" }}')
    if skill.include_types:
        lines.append(f"  {_type_test(skill.include_types)}")
    if skill.exclude_types:
        lines.append(f"  FILTER NOT EXISTS {{ {_type_test(skill.exclude_types)} }}")
    for mat in skill.exclude_materials:
        lines.append(
            "  FILTER NOT EXISTS { ?element twin:facingMaterial ?twin_material . "
            f'FILTER(REGEX(STR(?twin_material), {json.dumps(material_word_pattern(mat))}, "i")) }}'
        )
    if skill.sparql:
        lines.append("  { SELECT DISTINCT ?element WHERE {\n" + skill.sparql + "\n  } }")
    lines.append("}")
    return "\n".join(lines)
