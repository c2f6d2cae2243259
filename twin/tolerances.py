"""Tolerances of the live twin, in one place (metres and radians).

Maps: a solid's open mesh is filled where its section is made of closed loops, joining section
endpoints within :data:`SECTION_JOIN_M` (the rasteriser's other tolerances are in
:class:`twin.raster.Tolerances`).

A robot re-reports what it sees many times a second, each time with a little sensor noise. A report
whose geometry lies within these bounds of what the twin holds is a re-confirmation: it changes
nothing (no revision, no map work, no store write).
"""

from __future__ import annotations

from typing import Final

SAME_POSITION_M: Final = 1e-3
"""Every vertex of the reported geometry within 1 mm of the held one (world frame)."""

SAME_ANGLE_RAD: Final = 1e-4
"""The reported orientation within 0.1 mrad of the held one."""

SECTION_JOIN_M: Final = 1e-6
"""Two ends of a solid's section segments this close are one joint (1 um): far above the rounding
errors of T-junctions and of unwelded vertex copies (1e-12 m), far below any real gap."""
