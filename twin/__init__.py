"""building-twin core: the robot-independent graph world model of a building and the maps derived from it.

The core is a one-way stack of small modules::

    errors, records, meshops, vocab, grid      shared records and vocabulary (numpy only)
      <- meshcodec, store, config, skills      the graph store and what is read from it
      <- import_model, stats, scene            use cases on the graph
      <- raster <- maps                        slicing and rasterising skill maps
      <- cli, cli_map                          the ``twin`` command (wires in adapters)

``twin`` never imports ifcopenshell, Zenoh or Rerun: ``adapters`` translate between those and the
core's records. See ``README.md`` for the data flow.
"""

from __future__ import annotations

__version__ = "0.1.0"
