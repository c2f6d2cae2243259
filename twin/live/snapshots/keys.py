"""What a snapshot is keyed by: the store's identity, the code and configuration that shape maps, and
each skill profile; a snapshot whose keys differ is not used.

Example::

    keys = {"store": store_identity(store), "code": code_digest(), "config": config_digest(config)}
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from twin.config import Config
from twin.graph.store import GraphStore
from twin.selection.skills import SkillProfile

_CORE = Path(__file__).resolve().parents[2]
"""The core package (``twin/``): every module in it may shape maps, so every one keys the snapshot."""


def code_digest(root: Path = _CORE) -> str:
    """SHA-256 of the source of every module of the core (``twin/**/*.py``, by path relative to it).

    Keyed by the whole core rather than a hand-kept list of modules that shape maps: a list misses the
    module split out next (drawing, selection), and then an old snapshot's maps would be served as if
    current. A change anywhere in the core costs one rebuild on the next start; nothing is served stale.
    """
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(b"\0")
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
