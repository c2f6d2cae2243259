"""Many robots, one twin: the rules that decide what a robot's observation means.

:func:`twin.live.fuse.fuse` applies them in the order of docs/fusion.md's rules table, one module each:
:mod:`~twin.fusion.clocks` (sense time, stale), :mod:`~twin.fusion.associate` (which element a robot's
IRI is; the gates it shares with merge and absence in :mod:`~twin.fusion.gates`),
:mod:`~twin.fusion.history` (late news: previous poses), :mod:`~twin.fusion.confirm` (confirmation,
held and applied moves, sizes, disagreement between robots), :mod:`~twin.fusion.bias` (detector bias),
:mod:`~twin.fusion.merge`, :mod:`~twin.fusion.absence` (views and misses; what a view could see from
its sensor's origin, past the elements the twin holds, in :mod:`~twin.fusion.visibility`). Their
decisions go into a :class:`~twin.fusion.context.Fused`; the effects on the in-memory
:class:`~twin.fusion.memory.FusionMemory` (:mod:`~twin.fusion.effects`) apply once the observation's
plan is accepted. Geometry of footprints is in :mod:`~twin.fusion.footprints`; the per-storey pose
index in :mod:`~twin.fusion.poses`. Nothing here touches the store or imports :mod:`twin.live` at run
time.
"""
