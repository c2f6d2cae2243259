"""building-twin core: the robot-independent graph world model of a building and the maps derived from it.

The core is a one-way stack of small modules::

    errors, records, meshops, vocab, grid,     shared records and vocabulary (numpy only)
    gc_pause,
    ifc_classes, tolerances, lab_plan
      <- meshcodec, shapes, extents, rdf,      the graph store and what is read from it
         store, skill_selection, skills, config, lab_layout
      <- import_model, stats, scene,           use cases on the graph; observations in, events out
         observations, events
      <- raster <- maps                        slicing and rasterising skill maps
      <- live                                  the single writer: observations applied, maps patched

The ``twin`` command, the Zenoh daemon, the IFC reader and the Rerun recorder live in ``adapters``.
``twin`` never imports ifcopenshell, Zenoh or Rerun: ``adapters`` translate between those and the
core's records. See ``README.md`` for the data flow.
"""

from __future__ import annotations

__version__ = "0.1.0"
