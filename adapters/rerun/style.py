"""What an operator sees: element colours by IFC class, entity names, and the blueprint (the layout the
viewer opens on: the 3D building, one tab per storey with one top-down view per skill map, the event
log, the time panel on ``revision``)."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import numpy as np
import rerun.blueprint as rrb

from twin.live.events import ElementShape, TwinStarted

Rgba = tuple[int, int, int, int]

_SAFE = re.compile(r"[^A-Za-z0-9_-]+")

# Colours (RGBA) by IFC class family: what an operator tells apart at a glance.
_COLOURS: tuple[tuple[str, Rgba], ...] = (
    ("IfcOpeningElement", (255, 80, 80, 60)),
    ("IfcDoor", (200, 120, 40, 255)),
    ("IfcWindow", (120, 200, 255, 120)),
    ("IfcCurtainWall", (120, 200, 255, 120)),
    ("IfcFurnishingElement", (90, 170, 90, 255)),
    ("IfcFurniture", (90, 170, 90, 255)),
    ("IfcSlab", (170, 170, 170, 110)),
    ("IfcWall", (225, 215, 195, 110)),  # translucent: what robots observed inside stands out
    ("IfcColumn", (160, 160, 200, 255)),
    ("IfcBeam", (160, 160, 200, 255)),
)
_GLASS: Rgba = (120, 200, 255, 120)
OBSERVED: Rgba = (240, 60, 200, 255)
"""What robots added or moved: magenta, so it stands out in the translucent building."""
_DEFAULT: Rgba = (200, 200, 200, 255)


def colour_of(shape: ElementShape) -> Rgba:
    """The display colour of an element: glass by name, else by class (subtypes by prefix)."""
    if "glass" in shape.name.lower():
        return _GLASS
    for prefix, colour in _COLOURS:
        if shape.ifc_class.startswith(prefix):
            return colour
    return _DEFAULT


def entity_name(iri: str) -> str:
    """A short, path-safe entity name for an element IRI."""
    tail = iri.rstrip("/#").rsplit("#", 1)[-1].rsplit("/", 1)[-1]
    return _SAFE.sub("_", tail)[:80] or "element"


def top_down(
    elements: Sequence[ElementShape], storey: str, elevation: float
) -> rrb.archetypes.EyeControls3D | None:
    """A camera looking straight down on the storey's elements (None if it has none)."""
    points = [
        s.mesh.vertices @ s.placement[:3, :3].T + s.placement[:3, 3]
        for s in elements
        if s.storey == storey and len(s.mesh.vertices)
    ]
    if not points:
        return None
    xyz = np.concatenate(points)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    return looking_down(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]), elevation)


def looking_down(
    xmin: float, ymin: float, xmax: float, ymax: float, elevation: float
) -> rrb.archetypes.EyeControls3D:
    """A camera looking straight down on a rectangle at ``elevation``, all of it in sight."""
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    span = max(xmax - xmin, ymax - ymin, 1.0)
    return rrb.archetypes.EyeControls3D(
        position=[cx, cy - 0.01 * span, elevation + 1.1 * span],
        look_target=[cx, cy, elevation],
        eye_up=[0.0, 0.0, 1.0],
    )


def blueprint_of(event: TwinStarted, routes: Mapping[str, str] | None = None) -> rrb.Blueprint:
    """The layout of a daemon's recording: every storey and skill it started with, and the route
    graphs (``routes``: routes skill -> the navigation skill whose maps it is drawn over)."""
    storeys = [(storey, elevation) for storey, _, elevation in event.storeys]
    cameras = {storey: top_down(event.elements, storey, elevation) for storey, elevation in storeys}
    return blueprint(storeys, list(event.skills), cameras, routes)


def blueprint(
    storeys: Sequence[tuple[str, float]],
    skills: Sequence[str],
    cameras: Mapping[str, rrb.archetypes.EyeControls3D | None],
    routes: Mapping[str, str] | None = None,
) -> rrb.Blueprint:
    """The layout: the building and the event log on the left, a tab per storey on the right holding
    one top-down view per skill map (named by its skill, not stacked) and one per route graph (drawn
    over its navigation skill's map); the time panel on ``revision``."""
    routes = routes or {}
    maps = [
        rrb.Grid(
            *(
                rrb.Spatial3DView(
                    name=skill,
                    origin=f"maps/{storey}/{skill}",
                    contents=[f"maps/{storey}/{skill}/**"],
                    eye_controls=cameras.get(storey),
                )
                for skill in skills
            ),
            *(
                rrb.Spatial3DView(
                    name=f"{name} (routes)",
                    origin=f"maps/{storey}/{name}",
                    contents=[f"maps/{storey}/{name}/**", f"maps/{storey}/{navigation}/**"],
                    eye_controls=cameras.get(storey),
                )
                for name, navigation in sorted(routes.items())
            ),
            name=storey,
        )
        for storey, _ in storeys
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(name="building", origin="world", contents=["world/**", "maps/**"]),
                rrb.TextLogView(name="events", origin="events"),
                row_shares=[3, 1],
            ),
            rrb.Tabs(*maps) if maps else rrb.TextLogView(origin="events"),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(state="expanded", timeline="revision"),
    )
