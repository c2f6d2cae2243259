"""The compatibility gates shared by association, merge and absence: may fusion touch this element, is
a report of the same kind of object, and how well do two footprints match.

Example::

    is_candidate(state)                             # dynamic, not a zone
    compatible("IFC4", "IfcFurniture", state)       # the reported class fits the element's
    matches(rules.of(state.ifc_types), seen, held)  # 0: no match; higher is better
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.config.fusion import FusionClassRules
from twin.fusion.footprints import Pose, centre_distance, heights_overlap, iou
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
