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

Those products go to OpenCASCADE first. The check is shallow and cheap (about 0.06 s for the
1,660 elements of Janesville, with :class:`KernelChoice`'s caches): the body's items, looking through mapped
items, and the profile of a swept area; it does not walk faceted breps.

Example::

    reason = reference_reason(wall)          # "boolean result", "curved profile" or None
    routed = routed_products(f.by_type("IfcElement"))   # one KernelChoice for many products
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

REFERENCE_KERNEL = "opencascade"
"""The kernel whose meshes are taken as correct (tests compare every stored mesh against it)."""

_CURVED_PROFILES = ("IfcCircleProfileDef", "IfcEllipseProfileDef")
_CURVED_CURVES = ("IfcConic", "IfcBSplineCurve", "IfcTrimmedCurve", "IfcOffsetCurve2D")
_CURVED_SOLIDS = ("IfcRevolvedAreaSolid", "IfcSweptDiskSolid", "IfcSurfaceCurveSweptAreaSolid", "IfcCsgSolid")
_FILLETS = ("FilletRadius", "EdgeRadius", "FlangeEdgeRadius", "WebEdgeRadius", "InnerFilletRadius")


class KernelChoice:
    """Decides which products go to the reference kernel, remembering what it has looked at.

    Instances share representation maps and profiles, and one IFC class answers ``is_a`` the same way
    every time: the answers are kept (per router, so an edited file gets a new one), which makes the
    check about 3x faster on a furnished model.
    """

    def __init__(self) -> None:
        self._is_a: dict[tuple[str, str], bool] = {}
        self._mapped: dict[int, str | None] = {}
        self._profiles: dict[int, bool] = {}

    def _is(self, entity: Any, *classes: str) -> bool:
        """``entity.is_a(c)`` for any of ``classes`` (subtypes included), cached per entity class."""
        name = entity.is_a()
        for c in classes:
            key = (name, c)
            hit = self._is_a.get(key)
            if hit is None:
                hit = self._is_a[key] = bool(entity.is_a(c))
            if hit:
                return True
        return False

    def _curve_is_curved(self, curve: Any, depth: int = 0) -> bool:
        """True when ``curve`` has an arc or another non-straight part (polylines and segments are not)."""
        if curve is None or depth > 8:
            return False
        if self._is(curve, *_CURVED_CURVES):
            return True
        if self._is(curve, "IfcIndexedPolyCurve"):
            return any(self._is(seg, "IfcArcIndex") for seg in curve.Segments or ())
        if self._is(curve, "IfcCompositeCurve"):
            return any(self._curve_is_curved(seg.ParentCurve, depth + 1) for seg in curve.Segments or ())
        return False

    def _profile_is_curved(self, profile: Any) -> bool:
        if profile is None:
            return False
        known = self._profiles.get(profile.id())
        if known is None:
            known = self._profiles[profile.id()] = self._profile_check(profile)
        return known

    def _profile_check(self, profile: Any) -> bool:
        if self._is(profile, *_CURVED_PROFILES):
            return True
        if self._is(profile, "IfcArbitraryClosedProfileDef"):
            curves = [profile.OuterCurve]
            if self._is(profile, "IfcArbitraryProfileDefWithVoids"):
                curves.extend(profile.InnerCurves or ())
            return any(self._curve_is_curved(c) for c in curves)
        if self._is(profile, "IfcCompositeProfileDef"):
            return any(self._profile_is_curved(p) for p in profile.Profiles or ())
        if self._is(profile, "IfcDerivedProfileDef"):
            return self._profile_is_curved(profile.ParentProfile)
        info = profile.get_info(recursive=False)
        return any(info.get(name) for name in _FILLETS)

    def _item_reason(self, item: Any, depth: int = 0) -> str | None:
        if self._is(item, "IfcBooleanResult"):
            return "boolean result"
        if self._is(item, "IfcMappedItem"):
            if depth >= 8:
                return None
            source = item.MappingSource.MappedRepresentation
            if source.id() not in self._mapped:
                self._mapped[source.id()] = next(
                    (r for inner in source.Items or () if (r := self._item_reason(inner, depth + 1))), None
                )
            return self._mapped[source.id()]
        if self._is(item, *_CURVED_SOLIDS):
            return "curved solid"
        if self._is(item, "IfcSweptAreaSolid") and self._profile_is_curved(item.SweptArea):
            return "curved profile"
        return None

    def reason(self, product: Any) -> str | None:
        """Why ``product``'s body must be meshed by the reference kernel, or None when manifold is exact."""
        rep = getattr(product, "Representation", None)
        if rep is None:
            return None
        for representation in rep.Representations or ():
            for item in representation.Items or ():
                reason = self._item_reason(item)
                if reason is not None:
                    return reason
        return None


def reference_reason(product: Any) -> str | None:
    """Why ``product``'s body must be meshed by the reference kernel, or None when manifold is exact."""
    return KernelChoice().reason(product)


def routed_products(products: Iterable[Any]) -> list[Any]:
    """The products (in order) whose body must be meshed by the reference kernel."""
    router = KernelChoice()
    return [p for p in products if router.reason(p) is not None]
