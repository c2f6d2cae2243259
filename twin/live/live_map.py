"""One (storey, skill) map as the live twin keeps it, and the update a change of its cells makes.

Example::

    update = m.write(window, cells)   # None if no cell changed; else the map's next version
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from twin.live.overlay import MapKey
from twin.maps.grid import GridData, OccupancyGrid, Window
from twin.maps.raster import BoolArray
from twin.maps.render import MapPlan


@dataclass(frozen=True, eq=False, slots=True)
class WindowUpdate:
    """New cells of one map: ``data`` holds the values of ``window``; the map is now at ``version``."""

    storey: str
    skill: str
    window: Window
    data: GridData
    version: int


@dataclass(eq=False, slots=True)
class LiveMap:
    """One (storey, skill) map as the live twin keeps it."""

    plan: MapPlan
    base_mask: npt.NDArray[np.bool_]
    """Which base elements the skill selects."""
    overlay: set[str]
    """Which overlay elements the skill selects."""
    static: BoolArray
    """Occupancy (before inflation) of the selected, visible base elements, whole grid."""
    inside: BoolArray | None
    """Cells inside a space (only for ``unknown_outside`` skills)."""
    data: GridData
    version: int = 1

    @property
    def key(self) -> MapKey:
        return (self.plan.storey.key, self.plan.skill.name)

    def grid(self) -> OccupancyGrid:
        return OccupancyGrid(
            frame=self.plan.frame,
            data=self.data.copy(),
            storey=self.plan.storey.key,
            skill=self.plan.skill.name,
            elevation_m=self.plan.storey.elevation_m,
        )

    def write(self, window: Window, cells: GridData) -> WindowUpdate | None:
        """Make ``cells`` the values of ``window``; the update of the changed cells' bounding window,
        bringing the map to its next version, or None if no cell changed."""
        old = self.data[window.row0 : window.row1, window.col0 : window.col1]
        diff = cells != old
        rows = np.flatnonzero(diff.any(axis=1))
        if not len(rows):
            return None
        cols = np.flatnonzero(diff.any(axis=0))
        r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
        changed = Window(window.row0 + r0, window.col0 + c0, window.row0 + r1, window.col0 + c1)
        old[...] = cells
        self.version += 1
        data = self.data[changed.row0 : changed.row1, changed.col0 : changed.col1].copy()
        return WindowUpdate(self.plan.storey.key, self.plan.skill.name, changed, data, self.version)
