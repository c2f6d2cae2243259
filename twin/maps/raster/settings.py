"""Work sizes and the array types shared by the rasterising modules; their tolerances are the twin's
(:class:`twin.tolerances.Tolerances`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from twin.errors import MapError

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]
BoolArray = npt.NDArray[np.bool_]
Int8Array = npt.NDArray[np.int8]
Spans = tuple[IndexArray, IndexArray, IndexArray]  # (row, first column, last column), global cells

#: Polygon slots: a triangle clipped by two planes has at most 5 vertices.
MAX_VERTICES = 5


@dataclass(frozen=True, slots=True)
class RasterSettings:
    """Work sizes of rasterising: they change speed and memory, never the result.

    Attributes:
        chunk_triangles: triangles clipped at once (about 1 MB of input: the working set stays in cache).
        chunk_polygons: polygons rasterised at once.
        chunk_pairs: (polygon, row) pairs rasterised at once.
        tile_m: side, in metres, of the tiles :func:`slab_geometry` sorts each chunk's polygons by
            (the tile of their centre), so that runs of ``block`` polygons are compact.
        block: polygons per run whose bounds :class:`SlabGeometry` keeps as its window index.

    Example::

        tiny = RasterSettings(chunk_triangles=7, chunk_polygons=5, chunk_pairs=16, tile_m=0.3, block=3)
        assert (rasterize_slab(tri, el, closed, 0.0, 1.0, frame, settings=tiny) == full).all()
    """

    chunk_triangles: int = 1 << 14
    chunk_polygons: int = 1 << 15
    chunk_pairs: int = 1 << 17
    tile_m: float = 1.0
    block: int = 1 << 8

    def __post_init__(self) -> None:
        for name in ("chunk_triangles", "chunk_polygons", "chunk_pairs", "block"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                msg = f"RasterSettings.{name} must be a positive integer, got {value!r}."
                raise MapError(msg)
        if not (isinstance(self.tile_m, int | float) and 0 < self.tile_m < np.inf):
            msg = f"RasterSettings.tile_m must be a positive, finite number of metres, got {self.tile_m!r}."
            raise MapError(msg)


RASTER_SETTINGS = RasterSettings()
