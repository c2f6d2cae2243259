"""Skill profiles: which elements a robot skill's map is made of, and at which heights.

A profile is a typed record parsed from a TOML table or a JSON object. Two kinds of skill map:

- ``localization``: what a planar lidar at ``lidar_height_m`` sees: a slab of ``slab_thickness_m``
  centred on that height;
- ``navigation``: everything between ``floor_clearance_m`` and ``robot_height_m``, projected.

a point cloud for 3D lidars (NDT / ICP localizers):

- ``points``: the voxels of ``resolution_m`` (default 0.1 m) the selected surfaces touch between
  ``band_bottom_m`` (default -0.05: just below the floor's top, so the floor is in) and ``band_top_m``
  (default: up to the next storey's elevation), one point per voxel (see :mod:`twin.maps.points`);

and two kinds of nav2 costmap filter mask, made of the zones operators mark (same band as navigation):

- ``keepout``: the elements marked ``twin:keepout true``, as occupied (100) cells;
- ``speed``: the elements marked ``twin:speedLimit <limit_percent>``, as cells of value ``limit_percent``
  (nav2's speed filter, percent, base 0, multiplier 1). One profile per limit.

Virtual elements (``IfcVirtualElement``, e.g. a zone an operator drew) are in masks only, never in
localization or navigation maps.

Heights are relative to the storey's elevation. The element selection becomes one SPARQL query over
the graph (IFC types with their subtypes, BEO/FURN classes, materials, or a raw pattern on ``?element``):
see ``twin.selection.skill_selection``.

Example::

    skill = parse_skill("lab-navigation", {"kind": "navigation", "robot_height_m": 0.5})
    rows = store.select(selection_query(skill))
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import pyoxigraph as ox

from twin.errors import SkillError
from twin.graph import vocab
from twin.graph.rdf import uses_service
from twin.selection.skill_selection import class_iri, selection_query

__all__ = ["MASK_KINDS", "POINTS_RESOLUTION_M", "Kind", "SkillProfile", "parse_skill", "parse_skill_json"]

Kind = Literal["localization", "navigation", "keepout", "speed", "points"]
MASK_KINDS: tuple[Kind, ...] = ("keepout", "speed")
_NAME = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")
_IFC_NAME = re.compile(r"^Ifc[A-Za-z0-9]+$")

_COMMON = {
    "kind",
    "resolution_m",
    "include_types",
    "exclude_types",
    "exclude_materials",
    "sparql",
    "unknown_outside",
    "description",
}
_FIELDS: dict[str, set[str]] = {
    "localization": _COMMON | {"lidar_height_m", "slab_thickness_m"},
    "navigation": _COMMON | {"robot_height_m", "floor_clearance_m", "inflation_radius_m"},
    "keepout": _COMMON | {"robot_height_m", "floor_clearance_m"},
    "speed": _COMMON | {"robot_height_m", "floor_clearance_m", "limit_percent"},
    "points": (_COMMON - {"unknown_outside"}) | {"band_bottom_m", "band_top_m"},
}
POINTS_RESOLUTION_M = 0.1
"""A ``points`` skill's ``resolution_m`` (voxel size) unless it sets one."""


@dataclass(frozen=True, slots=True)
class SkillProfile:
    """A validated skill profile. Heights and sizes in metres."""

    name: str
    kind: Kind
    resolution_m: float = 0.05
    lidar_height_m: float = 0.5
    slab_thickness_m: float = 0.02
    robot_height_m: float = 1.5
    floor_clearance_m: float = 0.05
    inflation_radius_m: float = 0.0
    include_types: tuple[str, ...] = ()
    exclude_types: tuple[str, ...] = ()
    exclude_materials: tuple[str, ...] = ()
    sparql: str | None = None
    unknown_outside: bool = False
    description: str = ""
    limit_percent: int = 50
    """``speed`` masks: the limit of the zones they show (cells of that value)."""
    band_bottom_m: float = -0.05
    """``points``: the band's bottom relative to the storey's elevation (below 0: the floor's top is in)."""
    band_top_m: float | None = None
    """``points``: the band's top relative to the storey's elevation; None: the next storey's elevation
    (the top storey: the top of the model's geometry)."""

    @property
    def is_mask(self) -> bool:
        """A nav2 costmap filter mask (``keepout``, ``speed``), not a map of the building."""
        return self.kind in MASK_KINDS

    @property
    def occupied_value(self) -> int:
        """The cell value of what the map selects: 100, or a speed mask's ``limit_percent``."""
        return self.limit_percent if self.kind == "speed" else 100

    @property
    def z_range(self) -> tuple[float, float]:
        """``(z_lo, z_hi)`` of the slab relative to the storey's elevation."""
        if self.kind == "localization":
            half = self.slab_thickness_m / 2
            return (self.lidar_height_m - half, self.lidar_height_m + half)
        if self.kind == "points":
            return (self.band_bottom_m, 1e3 if self.band_top_m is None else self.band_top_m)
        return (self.floor_clearance_m, self.robot_height_m)

    def to_json(self) -> dict[str, Any]:
        """The profile as the JSON object :func:`parse_skill` accepts (only the kind's fields)."""
        out: dict[str, Any] = {}
        for key in sorted(_FIELDS[self.kind]):
            value = getattr(self, key)
            if isinstance(value, tuple):
                value = list(value)
            if value is None or value == [] or (key == "description" and not value):
                continue
            out[key] = value
        return out


def _number(name: str, key: str, value: Any, *, minimum: float, strict: bool, maximum: float = 1e3) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        msg = f"Skill {name!r}: field {key!r} must be a finite number of metres, got {value!r}."
        raise SkillError(msg)
    ok = value > minimum if strict else value >= minimum
    if not ok or value > maximum:
        bound = f"> {minimum}" if strict else f">= {minimum}"
        msg = f"Skill {name!r}: field {key!r} must be {bound} and <= {maximum}, got {value!r}."
        raise SkillError(msg)
    return float(value)


def _strings(name: str, key: str, value: Any, pattern: re.Pattern[str] | None = None) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) and v for v in value):
        msg = f"Skill {name!r}: field {key!r} must be a list of non-empty strings, got {value!r}."
        raise SkillError(msg)
    for v in value:
        if pattern is not None and not (pattern.match(v) or class_iri(v)):
            msg = (
                f"Skill {name!r}: field {key!r} has {v!r}, which is neither an IFC class name (IfcWall) "
                "nor a class CURIE/IRI (beo:Wall, <https://...>)."
            )
            raise SkillError(msg)
    return tuple(value)


def parse_skill(name: str, data: Mapping[str, Any]) -> SkillProfile:
    """Validate ``data`` (a TOML table or JSON object) into a profile; SkillError names the bad field."""
    if not isinstance(name, str) or not _NAME.match(name):
        msg = f"Skill name must be 1-64 of [a-z0-9_-] starting with a letter or digit, got {name!r}."
        raise SkillError(msg)
    if not isinstance(data, Mapping):
        msg = f"Skill {name!r} must be an object/table, got {type(data).__name__}."
        raise SkillError(msg)
    kind = data.get("kind")
    if not isinstance(kind, str) or kind not in _FIELDS:
        msg = (
            f"Skill {name!r}: field 'kind' must be 'localization', 'navigation', 'keepout', 'speed' or "
            f"'points', got {kind!r}."
        )
        raise SkillError(msg)
    unknown = sorted(set(data) - _FIELDS[kind])
    if unknown:
        others = [o for o in _FIELDS if o != kind and unknown[0] in _FIELDS[o]]
        close = difflib.get_close_matches(unknown[0], sorted(_FIELDS[kind]), n=1, cutoff=0.75)
        hint = (
            f" ({unknown[0]} belongs to {' and '.join(others)} skills)"
            if others
            else f" (did you mean {close[0]}?)"
            if close
            else ""
        )
        msg = f"Skill {name!r}: unknown field {unknown[0]!r}{hint}."
        raise SkillError(msg)
    args: dict[str, Any] = {"name": name, "kind": kind}
    if kind == "points":
        args["resolution_m"] = POINTS_RESOLUTION_M
    if "resolution_m" in data:
        args["resolution_m"] = _number(
            name, "resolution_m", data["resolution_m"], minimum=0.001, strict=False, maximum=10.0
        )
    for key in ("lidar_height_m", "robot_height_m"):
        if key in data:
            args[key] = _number(name, key, data[key], minimum=0.0, strict=True, maximum=100.0)
    for key in ("slab_thickness_m",):
        if key in data:
            args[key] = _number(name, key, data[key], minimum=0.0, strict=True, maximum=10.0)
    for key in ("band_bottom_m", "band_top_m"):
        if key in data:
            args[key] = _number(name, key, data[key], minimum=-100.0, strict=False, maximum=100.0)
    for key in ("floor_clearance_m", "inflation_radius_m"):
        if key in data:
            args[key] = _number(name, key, data[key], minimum=0.0, strict=False, maximum=100.0)
    if "include_types" in data:
        args["include_types"] = _strings(name, "include_types", data["include_types"], _IFC_NAME)
    if "exclude_types" in data:
        args["exclude_types"] = _strings(name, "exclude_types", data["exclude_types"], _IFC_NAME)
    if "exclude_materials" in data:
        args["exclude_materials"] = tuple(
            m.lower() for m in _strings(name, "exclude_materials", data["exclude_materials"])
        )
    if "limit_percent" in data:
        value = data["limit_percent"]
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 100:
            msg = f"Skill {name!r}: field 'limit_percent' must be an integer from 1 to 100, got {value!r}."
            raise SkillError(msg)
        args["limit_percent"] = value
    for key in ("unknown_outside",):
        if key in data:
            if not isinstance(data[key], bool):
                msg = f"Skill {name!r}: field {key!r} must be true or false, got {data[key]!r}."
                raise SkillError(msg)
            args[key] = data[key]
    if "description" in data:
        if not isinstance(data["description"], str):
            msg = f"Skill {name!r}: field 'description' must be a string."
            raise SkillError(msg)
        args["description"] = data["description"]
    if "sparql" in data:
        if not isinstance(data["sparql"], str) or not data["sparql"].strip():
            msg = f"Skill {name!r}: field 'sparql' must be a non-empty SPARQL group graph pattern."
            raise SkillError(msg)
        if uses_service(data["sparql"]):
            msg = f"Skill {name!r}: field 'sparql' may not use SERVICE (no remote queries)."
            raise SkillError(msg)
        args["sparql"] = data["sparql"]
    skill = SkillProfile(**args)
    if skill.kind == "points" and skill.resolution_m < 0.01:
        msg = (
            f"Skill {name!r}: field 'resolution_m' of a points skill must be >= 0.01, "
            f"got {skill.resolution_m}."
        )
        raise SkillError(msg)
    if skill.band_top_m is not None and skill.band_top_m <= skill.band_bottom_m:
        msg = (
            f"Skill {name!r}: field 'band_top_m' ({skill.band_top_m}) must be above "
            f"'band_bottom_m' ({skill.band_bottom_m})."
        )
        raise SkillError(msg)
    if skill.kind in ("navigation", "keepout", "speed") and skill.floor_clearance_m >= skill.robot_height_m:
        msg = (
            f"Skill {name!r}: field 'floor_clearance_m' ({skill.floor_clearance_m}) must be below "
            f"'robot_height_m' ({skill.robot_height_m})."
        )
        raise SkillError(msg)
    _check_query(skill)
    return skill


def parse_skill_json(name: str, payload: str | bytes) -> SkillProfile:
    """Parse a profile sent as JSON (e.g. over the wire); SkillError names what is wrong.

    Example::

        skill = parse_skill_json("tall", b'{"kind": "navigation", "robot_height_m": 2.0}')
    """
    size = len(payload.encode() if isinstance(payload, str) else payload)
    if size > 64 * 1024:
        msg = f"Skill {name!r}: JSON profile is {size} bytes, more than the 64 KiB allowed."
        raise SkillError(msg)
    try:
        data = json.loads(payload)
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        msg = f"Skill {name!r}: profile is not valid JSON: {err}."
        raise SkillError(msg) from err
    except RecursionError as err:
        msg = f"Skill {name!r}: profile JSON is nested too deeply."
        raise SkillError(msg) from err
    return parse_skill(name, data)


def _check_query(skill: SkillProfile) -> None:
    try:
        ox.Store().query(selection_query(skill), prefixes=vocab.PREFIXES)
    except SyntaxError as err:
        first = str(err).splitlines()[0] if str(err) else "syntax error"
        msg = f"Skill {skill.name!r}: field 'sparql' does not parse: {first}"
        raise SkillError(msg) from err
