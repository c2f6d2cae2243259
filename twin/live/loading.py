"""Load the live twin from the graph: the model node, the scene, the site frame and every state.

Example::

    live, base_iri = load_live(store, config)   # TwinError if the store holds no imported model
"""

from __future__ import annotations

import numpy as np

from twin.config import Config
from twin.errors import TwinError
from twin.live.live_maps import LiveMaps
from twin.live.skill_changes import stored_skills
from twin.live.state import LiveState, SiteFrame, StoreyFrame, load_states
from twin.scene import Scene, load_scene
from twin.store import GraphStore


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


def load_live(store: GraphStore, config: Config) -> tuple[LiveState, str]:
    """The live state of the twin in ``store`` (maps not built yet) and the model's base IRI."""
    model = store.select(
        "SELECT ?m ?schema ?rev WHERE { ?m a twin:Model . OPTIONAL { ?m twin:ifcSchema ?schema } "
        "OPTIONAL { ?m twin:revision ?rev } }"
    )
    if not model:
        msg = "The store holds no imported model (no twin:Model node): import one first."
        raise TwinError(msg)
    model_iri = model[0]["m"] or ""
    scene = load_scene(store)
    site = SiteFrame(
        storeys={s.key: StoreyFrame(s.key, s.iri, s.elevation_m) for s in scene.storeys},
        schema=(model[0]["schema"] or "IFC4"),
        static_types=config.import_.static_types,
        site_box=site_box(scene, config.limits.site_margin_m),
        model_iri=model_iri,
    )
    live = LiveState(
        site=site,
        maps=LiveMaps(scene, margin_m=config.margin_m),
        states=load_states(store),
        skills=stored_skills(store, dict(config.skills)),
        revision=max(int(r["rev"] or 0) for r in model),
        last_seen={},
        held={},
    )
    return live, model_iri.removesuffix("model")
