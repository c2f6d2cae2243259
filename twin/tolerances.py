"""The twin's numerical tolerances, in one frozen object (metres and radians).

Maps (:mod:`twin.maps.raster`, :mod:`twin.maps.meshops`): cells are shrunk or grown by ``cell_m``;
points within
``join_m`` are one point where the geometry must close: the ends of a section's segments, when a
solid's open mesh is filled where its section is made of closed loops, and the ends of a mesh's
edges along a line, when a surface is found to close around a volume.

Live observations (:mod:`twin.live.same`): a robot re-reports what it sees many times a second, each
time with a little sensor noise. A report whose geometry lies within ``same_position_m`` and
``same_angle_rad`` of what the twin holds is a re-confirmation: it changes nothing (no revision, no
map work, no store write).

Example::

    from twin.tolerances import TOLERANCES
    if np.abs(seen - held).max() <= TOLERANCES.same_position_m: ...
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Tolerances:
    """Numerical tolerances of the maps and of the live twin.

    Attributes:
        cell_m: 2D maps (:mod:`twin.maps.raster`): cells are shrunk (solid geometry) or grown
            (degenerate open surfaces) by this many metres when rasterising, after the vertices are
            taken to grid units by ``grid_m``'s rule; an open polygon is degenerate when its area is
            at most ``cell_m`` times its extent. It is sqrt(5)/2 nm, not a round number: a slanted
            edge whose corners are off the grid and which passes a round number of nanometres from a
            grid corner (a box turned 3-4-5, placed 1 nm off a grid line) is then clear of the shrunk
            cells' corners by far more than float noise, instead of touching one within that noise,
            which two ways of computing the same cells (:func:`twin.maps.raster.boxes.footprint_cells`
            and the general rasteriser) would decide differently.
        join_m: two points this close are one (1 um): the ends of section segments
            (:func:`twin.maps.raster.closed_sections`) and of edges along a line
            (:func:`twin.maps.meshops.closes_around`). Far above the rounding errors of T-junctions and of
            unwelded vertex copies (1e-12 m), far below any real gap.
        same_position_m: a re-reported geometry whose every world vertex is within this of the held
            one (1 mm) is the same.
        same_angle_rad: ... and whose orientation is within this of the held one (0.1 mrad).
        voxel_tie: points maps (:mod:`twin.maps.voxels`): the rounding bound, relative to the magnitudes
            involved (~450 ulp), under which a triangle's projection on a separating axis counts as a
            possible tie with a voxel's face, decided then in exact integer arithmetic.
        sliver_sin2: a triangle whose squared sine at its first corner is below this (its area is
            rounding: under a micrometre of width per metre) is taken as its edges when the nearest
            point to a voxel's centre is sought.
        grid_m: a coordinate within this (1 um) of a grid plane is on it (:mod:`twin.maps.grid`): of a
            grid line ``origin + i * resolution`` (the origin and the resolution read as the decimals
            they print as), of a voxel layer ``elevation + k * resolution``, of a band's end. The
            half-open rule then decides which cell it is in, so that where the building sits (a site
            moved by a whole number of cells, kilometres away) never changes a map. 2D maps apply it
            to every triangle's x and y before cutting it to the band, and to an upright box's
            corners on the live shortcut, then ``cell_m``'s rule decides.
        voxel_out_m, voxel_in_m: points maps (:func:`twin.maps.voxels.touched_pairs`): a triangle
            touches a voxel when it meets the voxel's half-open box with its lower faces moved out by
            ``voxel_out_m`` and its upper faces moved in by ``voxel_in_m`` (3.1 nm and 0.5 um). For a
            vertex that changes nothing (a coordinate within ``grid_m`` of a grid plane is on it, the
            others are farther), but a slanted surface that passes through a voxel's edge or corner
            with its vertices off the grid (a 30 degree roof through a grid line, a 45 degree wall
            through grid corners) is then clear of the moved box or into it by nanometres or more, far
            beyond float noise (1e-12 m at 10 km), instead of touching it within that noise, which a
            move of the building changes. The verdict is the half-open rule's on the exact geometry (a
            surface through a voxel's lower edge touches it, through an upper or a mixed one does
            not) unless the surface or edge is within 0.35 degrees of a grid plane or axis (a
            separating axis's components more than 161.8 to 1); the moves' ratio (161.8) is of no
            small whole numbers, so that no simple slope through a grid corner passes through a
            moved corner.
        point_quantum: points maps' ties (:func:`twin.maps.points.best_rows`): squared distances and
            points (in voxels) are compared rounded to this fraction of a voxel (2**-20, about 1e-6),
            so float noise of a few ulp never decides which of two equally near points a voxel keeps.
    """

    cell_m: float = 1.118034e-9  # sqrt(5) / 2 nm
    join_m: float = 1e-6
    same_position_m: float = 1e-3
    same_angle_rad: float = 1e-4
    voxel_tie: float = 1e-13
    sliver_sin2: float = 1e-12
    grid_m: float = 1e-6
    point_quantum: float = 2.0**-20
    voxel_out_m: float = 3.09017e-9
    voxel_in_m: float = 5e-7


TOLERANCES = Tolerances()
