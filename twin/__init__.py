"""building-twin core: the robot-independent graph world model of a building and the maps derived from it.

The core is a one-way stack of small modules::

    records  <- vocab <- meshcodec <- store <- skills <- grid/raster <- maps <- cli

``twin`` never imports ifcopenshell, Zenoh or Rerun: ``adapters`` translate between those and the
core's records. See ``README.md`` for the data flow.
"""

from __future__ import annotations

__version__ = "0.1.0"
