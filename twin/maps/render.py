"""Skill maps: slice the selected elements at a skill's heights and rasterise them on a storey's grid.

A map is planned once (:func:`plan_map`: frame, heights, selected elements) and rendered for any
window of its grid (:func:`render_window`); the full map is the full window. A window is computed
from only the elements whose bounds overlap it, and gives exactly the same cells as the full map (the
daemon re-slices only the regions that observations touch). One renderer turns occupancy into cell
values (inflation, unknown outside spaces) for every caller, the live twin's included
(:func:`render_cells`).

Example::

    scene = load_scene(store)
    iris = [row["element"].value for row in store.select(selection_query(skill))]
    plan = plan_map(scene, skill, "ground-floor", iris, margin_m=1.0)
    grid = build_map(scene, plan)                     # OccupancyGrid, 0 / 100 / -1
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from twin.errors import MapError
from twin.maps.grid import FREE, UNKNOWN, GridData, GridFrame, OccupancyGrid, Window
from twin.maps.raster import (
    BoolArray,
    SlabGeometry,
    closed_sections,
    rasterize,
    rasterize_slab,
    slab_geometry,
)
from twin.maps.scene import IndexArray, MeshSet, Scene, SlabBox, StoreyInfo
from twin.selection.skills import SkillProfile
from twin.tolerances import TOLERANCES

MAX_MAP_CELLS = 50_000_000
"""The largest skill map the twin builds (50 M cells: a 350 m x 350 m storey at 5 cm); any grid frame
may hold up to :data:`twin.maps.grid.MAX_FRAME_CELLS`."""


@dataclass(frozen=True, eq=False, slots=True)
class MapPlan:
    """Everything needed to render one (storey, skill) map: frame, world z slab, selected elements."""

    skill: SkillProfile
    storey: StoreyInfo
    frame: GridFrame
    z_lo: float
    z_hi: float
    selected: IndexArray
    spaces: IndexArray

    @property
    def inflation_cells(self) -> float:
        """The inflation radius in cells (0 for skills that do not inflate)."""
        return (
            self.skill.inflation_radius_m / self.frame.resolution_m
            if self.skill.kind == "navigation"
            else 0.0
        )

    @property
    def inflation_pad(self) -> int:
        """Whole cells the inflation reaches: how far beyond a window its occupancy is needed."""
        return whole_cells(self.inflation_cells)


def whole_cells(cells: float) -> int:
    """The whole cells within a distance of ``cells`` cells (a rounding error short of a whole counts)."""
    return math.floor(cells + 1e-9)


def plan_map(
    scene: Scene, skill: SkillProfile, storey_key: str, element_iris: Sequence[str], *, margin_m: float = 1.0
) -> MapPlan:
    """Fix the frame (storey extent + margin, snapped), the slab and the elements of one map."""
    storey = scene.storey(storey_key)
    if skill.unknown_outside and len(scene.spaces) == 0:
        msg = (
            f"Skill {skill.name!r} sets unknown_outside, but this model has no spaces (IfcSpace) to tell "
            "inside from outside; use a skill without unknown_outside."
        )
        raise MapError(msg)
    xmin, ymin, xmax, ymax = storey.extent
    frame = GridFrame.around(xmin, ymin, xmax, ymax, resolution_m=skill.resolution_m, margin_m=margin_m)
    if frame.width * frame.height > MAX_MAP_CELLS:
        msg = (
            f"Skill {skill.name!r}: resolution_m={skill.resolution_m} gives a {frame.width}x{frame.height} "
            f"grid for storey {storey_key!r}, more than {MAX_MAP_CELLS:,} cells; use a coarser resolution."
        )
        raise MapError(msg)
    lo, hi = skill.z_range
    spaces = [iri for iri, st in scene.space_storey.items() if st == storey.iri]
    return MapPlan(
        skill=skill,
        storey=storey,
        frame=frame,
        z_lo=storey.elevation_m + lo,
        z_hi=storey.elevation_m + hi,
        selected=scene.elements.indices_of(tuple(element_iris)),
        spaces=scene.spaces.indices_of(tuple(spaces)),
    )


@dataclass(frozen=True, eq=False, slots=True)
class PreparedSlab:
    """A plan's slab clipped once for a set of elements (e.g. the static ones), grid-independent.

    Any window is then rasterised from the prepared polygons without touching the triangles again;
    elements outside ``ids`` (e.g. what robots observed since) are rasterised from their triangles and
    OR-ed in (a map is the union of its elements' maps), so the result is the same bit for bit.
    """

    ids: IndexArray
    geometry: SlabGeometry


def filled(meshes: MeshSet, ids: IndexArray, plan: MapPlan) -> BoolArray:
    """``(len(ids),) bool``: which elements ``ids`` are filled in the plan's slab, not only outlined.

    A watertight mesh is; so is a solid's mesh that is not watertight (T-junctions, touching bodies,
    vertex copies) where its section at the slab's mid-height is made of closed loops
    (:func:`twin.maps.raster.closed_sections`). Decided per element from all of its triangles, so every
    window of a map agrees. Only solids with open meshes cost anything here.
    """
    fill = meshes.closed[ids]
    maybe = np.flatnonzero(meshes.solid[ids] & ~fill)
    if len(maybe):
        triangles, owner = meshes.triangles_of(ids[maybe])
        fill = fill.copy()
        fill[maybe] = closed_sections(triangles, owner, len(maybe), 0.5 * (plan.z_lo + plan.z_hi))
    return fill


def prepare_slab(scene: Scene, plan: MapPlan, ids: IndexArray | None = None) -> PreparedSlab:
    """Clip ``ids`` (default: every element the plan selects) to the plan's slab, once."""
    chosen = plan.selected if ids is None else np.intersect1d(ids, plan.selected)
    triangles, owner = scene.elements.triangles_of(chosen)
    fill = filled(scene.elements, chosen, plan)
    return PreparedSlab(chosen, slab_geometry(triangles, owner, fill, plan.z_lo, plan.z_hi, plan.frame))


def occupancy(meshes: MeshSet, ids: IndexArray, plan: MapPlan, window: Window) -> BoolArray:
    """Which cells of ``window`` the elements ``ids`` of ``meshes`` touch within the plan's slab."""
    f = plan.frame
    res, eps = f.resolution_m, 2 * TOLERANCES.grid_m  # within grid_m of the window's edge is on it
    box = SlabBox(
        xmin=f.origin_x + window.col0 * res - eps,
        ymin=f.origin_y + window.row0 * res - eps,
        xmax=f.origin_x + window.col1 * res + eps,
        ymax=f.origin_y + window.row1 * res + eps,
        z_lo=plan.z_lo - eps,  # within grid_m of the band's end is on it (raster.clip.snap_to_band)
        z_hi=plan.z_hi + eps,
    )
    near = meshes.overlapping(ids, box)
    if len(near) == 0:
        return np.zeros(window.shape, dtype=np.bool_)
    fill = filled(meshes, near, plan)
    if window == f.full:
        triangles, owner = meshes.triangles_of(near)
    else:
        triangles, owner = meshes.triangles_for_window(near, box, filled=fill)
    return rasterize_slab(triangles, owner, fill, plan.z_lo, plan.z_hi, f, window)


def dilate_disk(occupied: BoolArray, radius_cells: float) -> BoolArray:
    """Grow ``occupied`` by every cell whose centre is within ``radius_cells`` of an occupied centre.

    Vectorised as one horizontal run-length dilation (prefix sums) per row offset of the disk.
    """
    r = whole_cells(radius_cells)
    if r <= 0 or not occupied.any():
        return occupied.copy()
    h, w = occupied.shape
    prefix = np.zeros((h, w + 1), dtype=np.int32)
    np.cumsum(occupied, axis=1, out=prefix[:, 1:])
    cols = np.arange(w)
    runs: dict[int, BoolArray] = {}
    out = np.zeros_like(occupied)
    for dy in range(-r, r + 1):
        half = whole_cells(math.sqrt(max(radius_cells * radius_cells - dy * dy, 0.0)))
        run = runs.get(half)
        if run is None:
            hi = np.minimum(cols + half + 1, w)
            lo = np.maximum(cols - half, 0)
            run = runs[half] = (prefix[:, hi] - prefix[:, lo]) > 0
        # out[y] |= run[y + dy]
        if dy >= 0:
            out[: h - dy] |= run[dy:]
        else:
            out[-dy:] |= run[: h + dy]
    return out


Layer = tuple[MeshSet, IndexArray]
"""Elements to draw: a mesh set and the positions of the chosen elements in it."""


def render_cells(
    occupied_in: Callable[[Window], BoolArray],
    plan: MapPlan,
    window: Window,
    *,
    inside_in: Callable[[Window], BoolArray] | None = None,
) -> GridData:
    """The one map renderer: the ``(rows, cols) int8`` values of ``window`` of the plan's map (0 free,
    the skill's occupied value, -1 unknown), from where its elements' geometry lies.

    Args:
        occupied_in: the occupancy (before inflation) of a window, ``(rows, cols) bool``; asked once,
            for ``window`` grown by the plan's inflation pad (within the frame).
        plan: the map's plan (frame, skill, inflation).
        window: the cells wanted; clipped to the frame.
        inside_in: the cells of a window inside a space, for skills with ``unknown_outside`` (free
            cells outside every space are unknown); None otherwise.

    Every way of drawing a map (a whole map, a window, the live twin's windows) goes through here,
    so a window equals the same window of the full map bit for bit whoever draws it.
    """
    window = window.intersect(plan.frame.full)
    if window.empty:
        return np.zeros((max(window.shape[0], 0), max(window.shape[1], 0)), dtype=np.int8)
    pad = plan.inflation_pad
    padded = Window(window.row0 - pad, window.col0 - pad, window.row1 + pad, window.col1 + pad).intersect(
        plan.frame.full
    )
    occupied = occupied_in(padded)
    if pad:
        occupied = dilate_disk(occupied, plan.inflation_cells)
    r0, c0 = window.row0 - padded.row0, window.col0 - padded.col0
    occupied = occupied[r0 : r0 + window.shape[0], c0 : c0 + window.shape[1]]
    data = np.where(occupied, np.int8(plan.skill.occupied_value), FREE).astype(np.int8)
    if inside_in is not None:
        data[~inside_in(window) & ~occupied] = UNKNOWN
    return data


def _inside_spaces(spaces: MeshSet, plan: MapPlan) -> Callable[[Window], BoolArray] | None:
    """The cells of a window inside the plan's spaces, for skills with ``unknown_outside``."""
    if not plan.skill.unknown_outside:
        return None
    return lambda window: occupancy(spaces, plan.spaces, plan, window)


def render_window(
    scene: Scene, plan: MapPlan, window: Window, *, prepared: PreparedSlab | None = None
) -> GridData:
    """The ``(rows, cols) int8`` values of ``window`` of the plan's map: 0 free, 100 occupied, -1 unknown.

    With ``prepared``, its elements come from the prepared polygons (fast for repeated windows) and
    only the plan's other elements are sliced from their triangles; the cells are the same.
    """

    def occupied_in(padded: Window) -> BoolArray:
        if prepared is None:
            return occupancy(scene.elements, plan.selected, plan, padded)
        occupied = rasterize(prepared.geometry, plan.frame, padded)
        rest = np.setdiff1d(plan.selected, prepared.ids, assume_unique=True)
        if len(rest):
            occupied |= occupancy(scene.elements, rest, plan, padded)
        return occupied

    return render_cells(occupied_in, plan, window, inside_in=_inside_spaces(scene.spaces, plan))


def render_layers(layers: Sequence[Layer], plan: MapPlan, window: Window, *, spaces: MeshSet) -> GridData:
    """Like :func:`render_window`, for the union of several layers of elements (ignoring
    ``plan.selected``): what the live twin draws, the imported elements plus those robots changed."""

    def occupied_in(padded: Window) -> BoolArray:
        occupied = np.zeros(padded.shape, dtype=np.bool_)
        for meshes, ids in layers:
            if len(ids):
                occupied |= occupancy(meshes, ids, plan, padded)
        return occupied

    return render_cells(occupied_in, plan, window, inside_in=_inside_spaces(spaces, plan))


def build_map(scene: Scene, plan: MapPlan, *, prepared: PreparedSlab | None = None) -> OccupancyGrid:
    """The full map of ``plan``."""
    return OccupancyGrid(
        frame=plan.frame,
        data=render_window(scene, plan, plan.frame.full, prepared=prepared),
        storey=plan.storey.key,
        skill=plan.skill.name,
        elevation_m=plan.storey.elevation_m,
    )
