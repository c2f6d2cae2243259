"""Many robots, one twin: footprints and poses of elements, what robots saw and missed, aliases.

The pieces the writer (:mod:`twin.live.fuse`) uses to decide what an observation means: which
element a robot's own IRI is (:mod:`twin.fusion.footprints`: oriented footprints and their overlap),
whether a sighting confirms or moves it, what a view should have seen (:mod:`twin.fusion.visibility`:
its polygons by area, and what is visible from its sensor's origin past the elements the twin holds).
Pure functions and in-memory records; nothing here touches the store.
"""
