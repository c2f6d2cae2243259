"""Load the live twin from the graph: the model node, the scene, the site frame and every state, or
from the snapshot of them that the daemon kept (:mod:`twin.live.snapshots`) when it matches the store.

Example::

    live, base_iri = load_live(store, config)   # TwinError if the store holds no imported model
    live, base_iri, restored = load_live_or_restore(store, config, snapshots)
"""

from __future__ import annotations

import logging
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from twin.config import Config
from twin.errors import SnapshotError, TwinError
from twin.fusion.memory import Alias, FusionMemory
from twin.graph.rdf import Row
from twin.graph.store import GraphStore
from twin.live.live_maps import LiveMaps
from twin.live.skill_changes import stored_skills
from twin.live.snapshots import (
    Restored,
    Snapshots,
    code_digest,
    config_digest,
    replay,
    restore,
    store_identity,
)
from twin.live.state import LiveState, SiteFrame, StoreyFrame, load_states
from twin.maps.scene import Scene, load_scene
from twin.selection.skills import SkillProfile

log = logging.getLogger(__name__)


def site_box(scene: Scene, margin: float) -> tuple[float, float, float, float, float, float]:
    b = scene.elements.bounds
    b = b[~np.isnan(b).any(axis=1)]
    exts = np.array([s.extent for s in scene.storeys]) if scene.storeys else b[:, [0, 1, 3, 4]]
    return (
        float(min(exts[:, 0].min(), b[:, 0].min())) - margin,
        float(min(exts[:, 1].min(), b[:, 1].min())) - margin,
        float(b[:, 2].min()) - margin,
        float(max(exts[:, 2].max(), b[:, 3].max())) + margin,
        float(max(exts[:, 3].max(), b[:, 4].max())) + margin,
        float(b[:, 5].max()) + margin,
    )


def _model(store: GraphStore) -> list[Row]:
    model = store.select(
        "SELECT ?m ?schema ?rev WHERE { ?m a twin:Model . OPTIONAL { ?m twin:ifcSchema ?schema } "
        "OPTIONAL { ?m twin:revision ?rev } }"
    )
    if not model:
        msg = "The store holds no imported model (no twin:Model node): import one first."
        raise TwinError(msg)
    return model


def load_live(store: GraphStore, config: Config) -> tuple[LiveState, str]:
    """The live state of the twin in ``store`` (maps not built yet) and the model's base IRI."""
    live, base_iri, _ = load_live_or_restore(store, config, None)
    return live, base_iri


def load_live_or_restore(
    store: GraphStore, config: Config, snapshots: Snapshots | None
) -> tuple[LiveState, str, Restored | None]:
    """Like :func:`load_live`, from the snapshot when it matches the store (then the maps of its
    matching skills are there already, at the snapshot's revision: see :class:`Restored`)."""
    model = _model(store)
    model_iri = model[0]["m"] or ""
    revision = max(int(r["rev"] or 0) for r in model)
    skills = stored_skills(store, dict(config.skills))
    restored = _restore(store, config, snapshots, revision, skills) if snapshots is not None else None
    if restored is not None:
        scene, states = restored.maps.scene, restored.states
        restored.maps.points.max_points = config.max_points_per_storey  # (for skills added later)
    else:
        with ThreadPoolExecutor(1, thread_name_prefix="twin-load") as pool:
            # the store answers on its own threads: read the states while the meshes are decoded
            loading = pool.submit(load_states, store)
            scene = load_scene(store)
            states = loading.result()
    site = SiteFrame(
        storeys={s.key: StoreyFrame(s.key, s.iri, s.elevation_m) for s in scene.storeys},
        schema=(model[0]["schema"] or "IFC4"),
        static_types=config.import_.static_types,
        site_box=site_box(scene, config.limits.site_margin_m),
        model_iri=model_iri,
    )
    live = LiveState(
        site=site,
        maps=restored.maps
        if restored is not None
        else LiveMaps(scene, margin_m=config.margin_m, max_points=config.max_points_per_storey),
        states=states,
        skills=skills,
        revision=revision,
        last_seen={},
        held={},
        fusion=load_fusion(store, time.time_ns()),
        robot_storeys={n: r.storey for n, r in config.robots.items() if r.storey},
    )
    return live, model_iri.removesuffix("model"), restored


def _restore(
    store: GraphStore, config: Config, snapshots: Snapshots, revision: int, skills: dict[str, SkillProfile]
) -> Restored | None:
    """The live maps of the snapshot, if it matches the store (else log why not)."""
    t = time.perf_counter()
    snapshots.keys = {"store": store_identity(store), "code": code_digest(), "config": config_digest(config)}
    try:
        restored = restore(
            snapshots.path, keys=snapshots.keys, revision=revision, skills=skills, margin_m=config.margin_m
        )
    except SnapshotError as err:
        log.info("Rebuilding the maps from the store: %s", err)
        return None
    log.info(
        "Restored %d maps from the snapshot of revision %d (store at %d) in %.2f s",
        len(restored.maps.skill_maps),
        restored.revision,
        revision,
        time.perf_counter() - t,
    )
    snapshots.saved_revision = restored.revision
    return restored


def catch_up(store: GraphStore, live: LiveState, restored: Restored) -> None:
    """Bring maps restored from a snapshot up to the store: replay the elements changed since its
    revision (after a ``kill -9``), and count map versions from 1 as after a rebuild."""
    if restored.revision < live.revision:
        t = time.perf_counter()
        n = replay(store, live, restored.revision, before_base=restored.fill_near)
        log.info(
            "Replayed %d elements changed since the snapshot's revision %d in %.2f s",
            n,
            restored.revision,
            time.perf_counter() - t,
        )
    for m in live.maps.skill_maps.values():
        m.version = 1  # as after a rebuild: map versions count from 1 in each run of the daemon


def load_fusion(store: GraphStore, now_ns: int) -> FusionMemory:
    """The aliases and the elements said to be distinct, as the graph keeps them (each alias counts as
    used now: its time to live starts again at every start)."""
    memory = FusionMemory()
    for r in store.select("SELECT ?a ?t WHERE { ?a twin:aliasOf ?t }"):
        memory.aliases[r["a"] or ""] = Alias(r["t"] or "", now_ns)
    for r in store.select("SELECT ?e WHERE { ?e twin:distinct true }"):
        memory.distinct.add(r["e"] or "")
    return memory
