"""Independent references that building-twin is checked and measured against.

Each reference computes what the twin computes in another, simpler way that shares no code with it:
``slab_maps`` rasterises a mesh's slab cell by cell with trimesh and shapely (the oracle of
``twin.maps.raster``), and ``opencascade_maps`` builds every selected element's map straight from the IFC
file with OpenCASCADE (the oracle of the whole import-to-map path). The tests (``tests/``) and the
benchmarks (``benchmarks/map_reference.py``) both import them, so what the suite checks on the small
models and what the benchmark checks on the large ones cannot drift apart.

They use the development dependencies (trimesh, shapely) and are not installed with the package;
neither ``twin`` nor ``adapters`` imports them.
"""
