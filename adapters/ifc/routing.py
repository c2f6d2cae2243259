"""Which geometry kernel meshes which product.

The fast kernel (manifold) meshes extrusions of straight-edged profiles and triangulated or faceted
bodies exactly like OpenCASCADE, the reference kernel, and about ten times faster. Measured on the
shared corpus (every element meshed by both, compared by volume and world bounding box), it gets two
kinds of bodies wrong *without failing*:

- boolean results (``IfcBooleanResult``, ``IfcBooleanClippingResult``): walls clipped by a roof come
  back unclipped (FZK-Haus, Institute, Duplex);
- swept areas with curved profiles (circles, ellipses, curves with arcs, fillets): the
  profile is tessellated differently and often comes back as an open mesh (Janesville's chairs and
  beams, railings).

Those products go to OpenCASCADE first. The check is shallow and cheap (about 0.1 s for the
1,660 elements of Janesville): the body's items, looking through mapped items, and the profile of a
swept area; it does not walk faceted breps.

Example::

    reason = reference_reason(wall)          # "boolean result", "curved profile" or None
"""

from __future__ import annotations

from typing import Any

REFERENCE_KERNEL = "opencascade"
"""The kernel whose meshes are taken as correct (tests compare every stored mesh against it)."""

_CURVED_PROFILES = ("IfcCircleProfileDef", "IfcEllipseProfileDef")
_CURVED_CURVES = ("IfcConic", "IfcBSplineCurve", "IfcTrimmedCurve", "IfcOffsetCurve2D")
_CURVED_SOLIDS = ("IfcRevolvedAreaSolid", "IfcSweptDiskSolid", "IfcSurfaceCurveSweptAreaSolid", "IfcCsgSolid")
_FILLETS = ("FilletRadius", "EdgeRadius", "FlangeEdgeRadius", "WebEdgeRadius", "InnerFilletRadius")


def _curve_is_curved(curve: Any, depth: int = 0) -> bool:
    """True when ``curve`` has an arc or another non-straight part (polylines and line segments are not)."""
    if curve is None or depth > 8:
        return False
    if any(curve.is_a(t) for t in _CURVED_CURVES):
        return True
    if curve.is_a("IfcIndexedPolyCurve"):
        return any(seg.is_a("IfcArcIndex") for seg in curve.Segments or ())
    if curve.is_a("IfcCompositeCurve"):
        return any(_curve_is_curved(seg.ParentCurve, depth + 1) for seg in curve.Segments or ())
    return False


def _profile_is_curved(profile: Any) -> bool:
    if profile is None:
        return False
    if any(profile.is_a(t) for t in _CURVED_PROFILES):
        return True
    if profile.is_a("IfcArbitraryClosedProfileDef"):
        curves = [profile.OuterCurve]
        if profile.is_a("IfcArbitraryProfileDefWithVoids"):
            curves.extend(profile.InnerCurves or ())
        return any(_curve_is_curved(c) for c in curves)
    if profile.is_a("IfcCompositeProfileDef"):
        return any(_profile_is_curved(p) for p in profile.Profiles or ())
    if profile.is_a("IfcDerivedProfileDef"):
        return _profile_is_curved(profile.ParentProfile)
    info = profile.get_info(recursive=False)
    return any(info.get(name) for name in _FILLETS)


def _item_reason(item: Any, depth: int = 0) -> str | None:
    if item.is_a("IfcBooleanResult"):
        return "boolean result"
    if item.is_a("IfcMappedItem") and depth < 8:
        source = item.MappingSource
        for inner in source.MappedRepresentation.Items or ():
            reason = _item_reason(inner, depth + 1)
            if reason is not None:
                return reason
        return None
    if any(item.is_a(t) for t in _CURVED_SOLIDS):
        return "curved solid"
    if item.is_a("IfcSweptAreaSolid") and _profile_is_curved(item.SweptArea):
        return "curved profile"
    return None


def reference_reason(product: Any) -> str | None:
    """Why ``product``'s body must be meshed by the reference kernel, or None when manifold is exact."""
    rep = getattr(product, "Representation", None)
    if rep is None:
        return None
    for representation in rep.Representations or ():
        for item in representation.Items or ():
            reason = _item_reason(item)
            if reason is not None:
                return reason
    return None
