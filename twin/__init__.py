"""building-twin core: the robot-independent graph world model of a building and the maps derived from it.

The core is grouped as the paper's pipeline, a one-way stack of small subpackages::

    errors, records, tolerances, gc_pause, config/   shared records, tolerances and configuration
      <- graph/      the graph world model: vocab, rdf, store, meshcodec, extents, ifc_classes,
                     model_triples and import_model (records -> triples), stats
      <- selection/  skill profiles (skills) and the SPARQL of a skill's elements (skill_selection)
      <- maps/       scene (world triangles), raster/, render (one renderer), grid, meshops, shapes,
                     snapshot (array files), points and voxels (3D lidar clouds)
      <- fusion/     footprints and the memory of sightings (many robots, one twin)
      <- live/       the single writer: observations in, fuse, plan, commit, maps patched, events out
    samples/         the sample lab as plain data (written as IFC by adapters.ifc.sample_lab)

The ``twin`` command, the Zenoh daemon, the IFC reader and the Rerun recorder live in ``adapters``.
``twin`` never imports ifcopenshell, Zenoh or Rerun: ``adapters`` translate between those and the
core's records. See ``docs/concepts.md`` for the data flow.
"""

from __future__ import annotations

__version__ = "0.1.0"
