"""The live twin's derived state kept in a snapshot file, so that a restart neither decodes every mesh
nor renders every map.

What :meth:`~twin.live.service.TwinService.start` derives from the store (the scene: every element's
local mesh and placement, the spaces and storeys; and every map: its cells, its static occupancy, its
selection of base elements, its overlay) is written to one file (:mod:`twin.maps.snapshot`) next to the
store: on a clean stop, after a start that had to rebuild, and in the background while the daemon
runs (captured by the writer between two commits, compressed and written on another thread).

On start the file is used only when it verifies (its checksum) and every key matches: the store's
identity (the model node's IRI, source file, line count and schema), the code and configuration
that shape maps, and a revision not ahead of the store's. Maps are taken per skill, only for skill
profiles equal to the stored ones; others are built anew. A snapshot older than the store (after a
``kill -9``, or another writer) is brought up to date by replaying only the elements whose
``twin:revision`` is newer, through the same incremental path observations take, so the maps equal
a full rebuild. Anything else (missing, damaged, foreign, ahead) is logged and rebuilt from the store.

Example::

    snapshots = Snapshots(Path("var/store.snapshot"))
    service = TwinService(store, cfg, snapshot=snapshots)
    service.start()                                 # restored, or rebuilt and then saved
"""

from twin.live.snapshots.capture import Captured, Snapshots, capture, save, snapshot_path
from twin.live.snapshots.keys import code_digest, config_digest, skill_digest, store_identity
from twin.live.snapshots.restore import Restored, replay, restore

__all__ = [
    "Captured",
    "Restored",
    "Snapshots",
    "capture",
    "code_digest",
    "config_digest",
    "replay",
    "restore",
    "save",
    "skill_digest",
    "snapshot_path",
    "store_identity",
]
