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

from adapters.ifc.attributes import Attributes, Representations

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

    def __init__(
        self, representations: Representations | None = None, attributes: Attributes | None = None
    ) -> None:
        self._is_a: dict[tuple[str, tuple[str, ...]], bool] = {}
        self._mapped: dict[int, str | None] = {}
        self._profiles: dict[int, bool] = {}
        self._fillets: dict[str, tuple[int, ...]] = {}
        self._item_kinds: dict[str, str] = {}
        self._profile_kinds: dict[str, str] = {}
        self._attributes = attributes or Attributes()
        self._get = self._attributes.get
        self._representations = representations or Representations(self._attributes)

    def _is(self, entity: Any, *classes: str) -> bool:
        """``entity.is_a(c)`` for any of ``classes`` (subtypes included), cached per entity class."""
        key = (entity.is_a(), classes)
        hit = self._is_a.get(key)
        if hit is None:
            hit = self._is_a[key] = any(entity.is_a(c) for c in classes)
        return hit

    def _curve_is_curved(self, curve: Any, depth: int = 0) -> bool:
        """True when ``curve`` has an arc or another non-straight part (polylines and segments are not)."""
        if curve is None or depth > 8:
            return False
        if self._is(curve, *_CURVED_CURVES):
            return True
        get = self._get
        if self._is(curve, "IfcIndexedPolyCurve"):
            return any(self._is(seg, "IfcArcIndex") for seg in get(curve, "Segments") or ())
        if self._is(curve, "IfcCompositeCurve"):
            return any(
                self._curve_is_curved(get(seg, "ParentCurve"), depth + 1)
                for seg in get(curve, "Segments") or ()
            )
        return False

    def _profile_is_curved(self, profile: Any) -> bool:
        if profile is None:
            return False
        known = self._profiles.get(profile.id())
        if known is None:
            known = self._profiles[profile.id()] = self._profile_check(profile)
        return known

    def _profile_kind(self, profile: Any) -> str:
        """What :meth:`_profile_check` does with a profile of this class (the first test that holds)."""
        name = profile.is_a()
        kind = self._profile_kinds.get(name)
        if kind is None:
            tests = (
                ("curved", _CURVED_PROFILES),
                ("voids", ("IfcArbitraryProfileDefWithVoids",)),
                ("arbitrary", ("IfcArbitraryClosedProfileDef",)),
                ("composite", ("IfcCompositeProfileDef",)),
                ("derived", ("IfcDerivedProfileDef",)),
            )
            kind = next((k for k, classes in tests if self._is(profile, *classes)), "parametric")
            self._profile_kinds[name] = kind
        return kind

    def _profile_check(self, profile: Any) -> bool:
        kind = self._profile_kind(profile)
        if kind == "curved":
            return True
        get = self._get
        if kind in ("arbitrary", "voids"):
            curves = [get(profile, "OuterCurve")]
            if kind == "voids":
                curves.extend(get(profile, "InnerCurves") or ())
            return any(self._curve_is_curved(c) for c in curves)
        if kind == "composite":
            return any(self._profile_is_curved(p) for p in get(profile, "Profiles") or ())
        if kind == "derived":
            return self._profile_is_curved(get(profile, "ParentProfile"))
        return self._has_fillet(profile)

    def _has_fillet(self, profile: Any) -> bool:
        """``any(profile.get_info().get(name) for name in _FILLETS)``, without building the dict.

        ``get_info`` reads every attribute and logs (and skips) one that cannot be read: every
        attribute is read here too, and a profile with one that cannot be read goes to ``get_info``."""
        name = profile.is_a(True)
        fillets = self._fillets.get(name)
        if fillets is None:
            names = profile.get_attribute_names()
            fillets = self._fillets[name] = tuple(i for i, n in enumerate(names) if n in _FILLETS)
        try:
            values = [profile.get_argument(i) for i in range(len(profile))]
        except Exception:  # get_info reports it (and goes on), as it always did
            info = profile.get_info(recursive=False)
            return any(info.get(n) for n in _FILLETS)
        return any(values[i] for i in fillets)

    def _item_kind(self, item: Any) -> str:
        """What :meth:`_item_reason` does with an item of this class (the first test that holds)."""
        name = item.is_a()
        kind = self._item_kinds.get(name)
        if kind is None:
            tests = (
                ("boolean", ("IfcBooleanResult",)),
                ("mapped", ("IfcMappedItem",)),
                ("curved", _CURVED_SOLIDS),
                ("swept", ("IfcSweptAreaSolid",)),
            )
            kind = self._item_kinds[name] = next((k for k, classes in tests if self._is(item, *classes)), "")
        return kind

    def _item_reason(self, item: Any, depth: int = 0) -> str | None:
        kind = self._item_kind(item)
        if kind == "boolean":
            return "boolean result"
        if kind == "mapped":
            if depth >= 8:
                return None
            get = self._get
            source = get(get(item, "MappingSource"), "MappedRepresentation")
            if source.id() not in self._mapped:
                self._mapped[source.id()] = next(
                    (
                        r
                        for inner in self._representations.items(source)
                        if (r := self._item_reason(inner, depth + 1))
                    ),
                    None,
                )
            return self._mapped[source.id()]
        if kind == "curved":
            return "curved solid"
        if kind == "swept" and self._profile_is_curved(self._get(item, "SweptArea")):
            return "curved profile"
        return None

    def reason(self, product: Any) -> str | None:
        """Why ``product``'s body must be meshed by the reference kernel, or None when manifold is exact."""
        representations = self._representations.of(product)
        if representations is None:
            return None
        for representation in representations:
            for item in self._representations.items(representation):
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
