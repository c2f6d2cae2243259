"""The compatibility gates shared by association, merge and absence: may fusion touch this element, is
a report of the same kind of object, and how well do two footprints match.

Example::

    is_candidate(state)                             # dynamic, not a zone
    compatible("IFC4", "IfcFurniture", state)       # the reported class fits the element's
    matches(rules.of(state.ifc_types), seen, held)  # 0: no match; higher is better
    sizes_agree(rules.of(state.ifc_types), seen, held)   # a chair is not the table it stands under
    kinds_agree("IFC4", report, state)              # furn:Chair is not furn:Table
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

from twin.config.fusion import FusionClassRules
from twin.fusion.footprints import Pose, centre_distance, corners, heights_overlap, iou, points_in_polygon
from twin.graph import vocab
from twin.graph.ifc_classes import supertypes
from twin.selection.skill_selection import VIRTUAL_TYPE

if TYPE_CHECKING:
    from twin.live.state import ElementState


def is_candidate(state: ElementState) -> bool:
    """Whether fusion may associate, merge or remove by absence this element: dynamic, not a zone."""
    return not (
        state.removed
        or state.is_static
        or state.keepout
        or state.speed_limit
        or VIRTUAL_TYPE in state.ifc_types
    )


def compatible(schema: str, reported: str, state: ElementState) -> bool:
    """The reported class is the element's class, a supertype of it, or a subtype of it."""
    if reported in state.ifc_types:
        return True
    chain = supertypes(schema, reported)
    return chain is not None and state.ifc_class in chain


def matches(rules: FusionClassRules, a: Pose, b: Pose) -> float:
    """How well ``a`` matches ``b`` (0: not at all): their IoU, or for small objects a score by
    centre distance."""
    if not heights_overlap(a, b):
        return 0.0
    if max(a.sx, b.sx) < rules.small_object_m:
        d = centre_distance(a, b)
        return 0.0 if d > rules.centre_distance_m else 1.0 - d / max(rules.centre_distance_m, 1e-9) / 2
    value = iou(a, b)
    return value if value >= rules.min_iou else 0.0


def sizes_agree(rules: FusionClassRules, seen: Pose, held: Pose) -> bool:
    """Each horizontal side and the height of ``seen`` within ``size_ratio`` of ``held``'s, and the
    smaller footprint area at least ``min_area_ratio`` of the larger (poses are canonical: ``sx >= sy``)."""
    ratio = rules.size_ratio
    if abs(seen.sx - held.sx) > ratio * held.sx or abs(seen.sy - held.sy) > ratio * held.sy:
        return False
    if abs(seen.sz - held.sz) > ratio * held.sz:
        return False
    small, large = sorted((seen.area, held.area))
    return large <= 0.0 or small / large >= rules.min_area_ratio


def lies_within(seen: Pose, held: Pose, *, margin_m: float) -> bool:
    """Whether ``seen``'s footprint lies inside ``held``'s grown by ``margin_m`` (a partly hidden
    object's box: smaller than the object, within it)."""
    reach = math.hypot(max(held.sx / 2 + margin_m, 0.0), max(held.sy / 2 + margin_m, 0.0))
    if centre_distance(seen, held) > reach + 1e-6:
        return False  # its centre (its corners' mean) is outside the grown footprint's circle: a corner too
    return bool(points_in_polygon(corners(seen), corners(held, inset=-margin_m)).all())


def descriptive_types(
    schema: str, classes: frozenset[str] | tuple[str, ...], ifc_class: str
) -> frozenset[str]:
    """The descriptive types among ``classes`` (``furn:Chair``): the BEO and FURN classes beyond the
    generic one of the IFC class and its supertypes (``furn:Furniture`` says no more than IfcFurniture)."""
    generic = _generic_types(schema, ifc_class)
    return frozenset(c for c in classes if c != vocab.BOT_ELEMENT and c not in generic)


@functools.lru_cache(maxsize=1024)
def _generic_types(schema: str, ifc_class: str) -> frozenset[str | None]:
    """The BEO and FURN classes of ``ifc_class`` and its supertypes (a pure function of the schema's
    class table: computed once per class, not once per report)."""
    return frozenset(vocab.semantic_class(t) for t in (supertypes(schema, ifc_class) or (ifc_class,)))


def kinds_agree(schema: str, classes: tuple[str, ...], ifc_class: str | None, state: ElementState) -> bool:
    """A report's descriptive types (``classes``) and the element's share one, or one side has none."""
    mine = descriptive_types(schema, state.classes, state.ifc_class)
    if not mine:
        return True
    theirs = descriptive_types(schema, classes, ifc_class or state.ifc_class)
    return not theirs or bool(mine & theirs)
