"""Why is this map cell what it is? The elements that occupy it, or why the ones near it do not.

For a point of a (storey, skill) map: the cell's value; the selected elements whose own occupancy
touches the cell (within the inflation radius for an inflated map), each with its class, name,
GlobalId and, for what robots observed, who saw it, when and at which revision; and the elements near
the point (``near_m``) that the skill does not draw, each with the reason (excluded type, a glass
material, an open door, outside the height band, a virtual element, not marked as a zone). Operators
ask this of a robot that will not drive through a door.

Example::

    answer = explain_cell(live, store, "ground-floor", "navigation", x=16.6, y=7.0)
    answer["value"], [e["name"] for e in answer["occupied_by"]]
"""

from __future__ import annotations

import math
from typing import Any

from twin.errors import ExplainError
from twin.fusion.clocks import clock_offsets
from twin.graph import vocab
from twin.graph.store import GraphStore
from twin.live.membership import rejection
from twin.live.state import ElementState, LiveState
from twin.maps.grid import Window
from twin.selection.skills import SkillProfile
from twin.tolerances import TOLERANCES

NEAR_M = 1.0
"""How far from the point elements count as near, metres (default)."""


def why_not(skill: SkillProfile, state: ElementState, bounds: Any, z_lo: float, z_hi: float) -> str:
    """Why ``skill`` does not draw the element (it has geometry near the point): the selection's own
    reason (:func:`~twin.live.membership.rejection`), else its place outside the height band."""
    reason = rejection(skill, state, has_geometry=True)
    if reason is not None:
        return reason
    if bounds[5] < z_lo or bounds[2] > z_hi:
        return f"outside the height band {z_lo:.2f}-{z_hi:.2f} m (element {bounds[2]:.2f}-{bounds[5]:.2f} m)"
    g = TOLERANCES.grid_m
    if bounds[5] <= z_lo + g or bounds[2] >= z_hi - g:
        return (
            f"only touches the end of the height band {z_lo:.2f}-{z_hi:.2f} m (element {bounds[2]:.2f}-"
            f"{bounds[5]:.2f} m): a solid there occupies no space in the band"
        )
    return "selected, but its geometry does not touch this cell"


def _details(store: GraphStore, iris: list[str]) -> dict[str, dict[str, str | None]]:
    """GlobalId and latest provenance of each element, from the graph."""
    if not iris:
        return {}
    values = " ".join(f"<{i}>" for i in iris)
    rows = store.select(
        f"""SELECT ?e ?gid ?by ?at ?rev WHERE {{
              VALUES ?e {{ {values} }}
              OPTIONAL {{ ?e <{vocab.PROPS_GLOBAL_ID}> ?gid }}
              OPTIONAL {{ ?e twin:observedBy ?by }}
              OPTIONAL {{ ?e twin:observedAt ?at }}
              OPTIONAL {{ ?e twin:revision ?rev }}
            }}"""
    )
    return {
        r["e"] or "": {"global_id": r["gid"], "by": r["by"], "at": r["at"], "rev": r["rev"]} for r in rows
    }


def _describe(iri: str, state: ElementState | None, d: dict[str, str | None]) -> dict[str, Any]:
    out: dict[str, Any] = {
        "iri": iri,
        "class": state.ifc_class if state else None,
        "name": state.name if state else None,
        "global_id": d.get("global_id"),
    }
    if d.get("by") is not None:
        out["observed"] = {
            "robot": d["by"],
            "at": d.get("at"),
            "revision": int(rev) if (rev := d.get("rev")) else None,
        }
    return out


def explain_cell(
    live: LiveState, store: GraphStore, storey: str, skill: str, *, x: float, y: float, near_m: float = NEAR_M
) -> dict[str, Any]:
    """What occupies the cell of map (``storey``, ``skill``) at world ``(x, y)``, or why it is free.

    Raises ExplainError naming an unknown map or a point outside it.
    """
    if not (math.isfinite(x) and math.isfinite(y)):
        msg = f"The point must have finite coordinates, got x={x!r}, y={y!r}."
        raise ExplainError(msg)
    m = live.maps.skill_maps.get((storey, skill))
    if m is None:
        known = ", ".join(f"{s}/{k}" for s, k in sorted(live.maps.skill_maps)) or "none"
        msg = f"No map {storey}/{skill}; the twin's maps are {known}."
        raise ExplainError(msg)
    f, plan = m.plan.frame, m.plan
    col = math.floor((x - f.origin_x) / f.resolution_m)
    row = math.floor((y - f.origin_y) / f.resolution_m)
    if not (0 <= row < f.height and 0 <= col < f.width):
        msg = (
            f"Point ({x}, {y}) is outside the map {storey}/{skill} "
            f"(x {f.origin_x:.2f}..{f.origin_x + f.width * f.resolution_m:.2f}, "
            f"y {f.origin_y:.2f}..{f.origin_y + f.height * f.resolution_m:.2f})."
        )
        raise ExplainError(msg)
    pad = plan.inflation_pad
    cell = Window(row, col, row + 1, col + 1)
    occupied = live.maps.elements_at((storey, skill), cell)
    inflated = []
    if pad and not occupied:
        grown = Window(row - pad, col - pad, row + pad + 1, col + pad + 1).intersect(f.full)
        inflated = live.maps.elements_at((storey, skill), grown)
    near = []
    profile = live.skills[skill]
    for iri, state in live.states.items():
        b = live.maps.bounds_of(iri)
        if b is None or iri in occupied or iri in inflated:
            continue
        dx = max(b[0] - x, 0.0, x - b[3])
        dy = max(b[1] - y, 0.0, y - b[4])
        if math.hypot(dx, dy) > near_m or b[5] < plan.storey.elevation_m - 0.5:
            continue
        if b[2] > plan.storey.elevation_m + 10.0:
            continue
        reason = why_not(profile, state, b, plan.z_lo, plan.z_hi)
        near.append((math.hypot(dx, dy), iri, state, reason))
    near.sort(key=lambda t: (t[0], t[1]))
    details = _details(store, [*occupied, *inflated, *(i for _, i, _, _ in near)])
    value = int(m.data[row, col])
    answer = {
        "storey": storey,
        "skill": skill,
        "x": x,
        "y": y,
        "cell": {"col": col, "row": row},
        "value": value,
        "state": "occupied" if value > 0 else ("unknown" if value < 0 else "free"),
        "occupied_by": [_describe(i, live.states.get(i), details.get(i, {})) for i in occupied],
        "within_inflation_of": [_describe(i, live.states.get(i), details.get(i, {})) for i in inflated],
        "near": [
            {**_describe(i, s, details.get(i, {})), "distance_m": round(d, 3), "why_not": r}
            for d, i, s, r in near[:20]
        ],
    }
    for key in ("occupied_by", "within_inflation_of", "near"):
        for entry in answer[key]:  # type: ignore[attr-defined]
            fused = fusion_of(live, entry["iri"])
            if fused:
                entry["fusion"] = fused
    return answer


def fusion_of(live: LiveState, iri: str) -> dict[str, Any]:
    """What fusion knows of an element: the robots that saw it (how often, first and last) and their
    clock offsets, the robot IRIs that resolve to it, the views that missed it since its last sighting,
    a move or resize noted but not confirmed, and the rule that decided its latest report."""
    out: dict[str, Any] = {}
    track = live.fusion.tracks.get(iri)
    if track is not None:
        out.update(track.as_json())
        offsets = clock_offsets(live.fusion)
        robots = {*track.robots, *(m.robot for m in track.misses)}
        seen = {r: offsets[r] for r in sorted(robots) if r in offsets}
        if seen:
            out["clock_offsets"] = seen
    aliases = live.fusion.aliases_of(iri)
    if aliases:
        out["aliases"] = aliases
    return out


__all__ = ["NEAR_M", "explain_cell", "fusion_of", "why_not"]
