"""What a snapshot is keyed by: the store's identity, the code and configuration that shape maps, and
each skill profile; a snapshot whose keys differ is not used.

Example::

    keys = {"store": store_identity(store), "code": code_digest(), "config": config_digest(config)}
"""

from __future__ import annotations

import hashlib
import importlib
import json
from pathlib import Path

from twin.config import Config
from twin.skills import SkillProfile
from twin.store import GraphStore

_SHAPING_MODULES = (
    "twin.grid",
    "twin.maps",
    "twin.meshcodec",
    "twin.scene",
    "twin.skills",
    "twin.snapshot",
    "twin.live.live_map",
    "twin.live.live_maps",
    "twin.live.overlay",
    "twin.live.snapshots.capture",
    "twin.live.snapshots.restore",
)
"""The code that decides what a map holds: a snapshot written by other code is rebuilt."""


def code_digest() -> str:
    """SHA-256 of the source of every module that shapes maps (and of the raster package)."""
    h = hashlib.sha256()
    files: list[Path] = []
    for name in _SHAPING_MODULES:
        files.append(Path(str(importlib.import_module(name).__file__)))
    raster = importlib.import_module("twin.raster")
    files += sorted(Path(str(raster.__file__)).parent.glob("*.py"))
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:32]


def skill_digest(skill: SkillProfile) -> str:
    return hashlib.sha256(json.dumps(skill.to_json(), sort_keys=True).encode()).hexdigest()[:32]


def config_digest(config: Config) -> str:
    """What of the configuration shapes maps besides the skills."""
    shaping = {"margin_m": config.margin_m, "static_types": list(config.import_.static_types)}
    return hashlib.sha256(json.dumps(shaping, sort_keys=True).encode()).hexdigest()[:32]


def store_identity(store: GraphStore) -> dict[str, str]:
    """The imported model the store holds (its IRI, source file, line count and schema)."""
    rows = store.select(
        "SELECT ?m ?src ?lines ?schema WHERE { ?m a twin:Model . OPTIONAL { ?m twin:sourceFile ?src } "
        "OPTIONAL { ?m twin:sourceLines ?lines } OPTIONAL { ?m twin:ifcSchema ?schema } } ORDER BY ?m"
    )
    return {
        "model": ",".join(r["m"] or "" for r in rows),
        "source": ",".join(r["src"] or "" for r in rows),
        "lines": ",".join(r["lines"] or "" for r in rows),
        "schema": ",".join(r["schema"] or "" for r in rows),
    }


# --- capture (writer thread) and write (any thread) ------------------------------------------------
