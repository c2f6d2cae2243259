"""Statistics of a graph world model: the paper's Table 1 and more.

Example::

    with EmbeddedStore.open(Path("lab.store"), read_only=True) as store:
        print(model_stats(store).as_dict())
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.scene import STOREY_MEMBER


@dataclass(frozen=True, slots=True)
class StoreyStats:
    key: str
    name: str
    elevation_m: float
    spaces: int
    elements: int


@dataclass(frozen=True, slots=True)
class ModelStats:
    """Table 1 (IFC lines, triples, Turtle bytes, elements, meshes) plus spaces, storeys and classes."""

    source: str
    schema: str
    ifc_lines: int
    triples: int
    turtle_bytes: int
    elements: int
    meshes: int
    triangles: int
    spaces: int
    storeys: tuple[StoreyStats, ...]
    elements_per_class: dict[str, int]
    mesh_failures: int
    kernel_fallbacks: int
    failed_elements: tuple[str, ...] = ()
    meshes_per_kernel: dict[str, int] = field(default_factory=dict)
    """Elements meshed by each geometry kernel (``twin:meshKernel``): OpenCASCADE meshes what manifold
    gets wrong (boolean results, curved profiles), manifold the rest."""
    removed: int = 0
    """Elements a robot removed: kept in the graph as tombstones (``twin:removed true``, no geometry), so
    that the removal's time stays known (a robot-added element's for ``[fusion] tombstone_ttl_s``), and
    left out of every other count."""

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


CURRENT = "FILTER NOT EXISTS { ?e twin:removed true }"
"""Keeps ``?e`` to the elements the twin holds now (not the tombstones of removed ones)."""


def _count(store: GraphStore, pattern: str) -> int:
    rows = store.select(f"SELECT (COUNT(*) AS ?n) WHERE {{ {pattern} }}")
    return int(literal_value(rows[0]["n"]) or 0)


def model_stats(store: GraphStore, *, turtle: bool = True) -> ModelStats:
    """Compute the statistics; ``turtle=False`` skips measuring the Turtle size (reported as -1)."""
    meta = store.select(
        "SELECT ?src ?schema ?lines WHERE { ?m a twin:Model ; twin:sourceFile ?src ; "
        "twin:ifcSchema ?schema ; twin:sourceLines ?lines }"
    )
    src, schema, lines = ("", "", 0)
    if meta:
        src = literal_value(meta[0]["src"]) or ""
        schema = literal_value(meta[0]["schema"]) or ""
        lines = int(literal_value(meta[0]["lines"]) or 0)
    storeys = tuple(
        StoreyStats(
            key=literal_value(r["key"]) or "",
            name=literal_value(r["name"]) or "",
            elevation_m=float(literal_value(r["elev"]) or 0.0),
            spaces=int(literal_value(r["spaces"]) or 0),
            elements=int(literal_value(r["elements"]) or 0),
        )
        for r in store.select(
            f"""SELECT ?key ?name ?elev (COUNT(DISTINCT ?sp) AS ?spaces) (COUNT(DISTINCT ?el) AS ?elements)
               WHERE {{
                 ?st a bot:Storey ; twin:storeyKey ?key ; twin:elevation ?elev .
                 OPTIONAL {{ ?st rdfs:label ?name }}
                 OPTIONAL {{ ?st bot:hasSpace ?sp }}
                 OPTIONAL {{ ?st {STOREY_MEMBER} ?el FILTER NOT EXISTS {{ ?el twin:removed true }} }}
               }} GROUP BY ?key ?name ?elev ORDER BY ?elev ?key"""
        )
    )
    per_class = {
        literal_value(r["cls"]) or "": int(literal_value(r["n"]) or 0)
        for r in store.select(
            f"SELECT ?cls (COUNT(?e) AS ?n) WHERE {{ ?e a bot:Element ; twin:ifcClass ?cls {CURRENT} }} "
            "GROUP BY ?cls ORDER BY DESC(?n) ?cls"
        )
    }
    tri_rows = store.select(
        "SELECT (SUM(?t) AS ?n) WHERE { ?e a bot:Element ; omg:hasGeometry ?g . ?g twin:triangleCount ?t "
        f"{CURRENT} }}"
    )
    return ModelStats(
        source=src,
        schema=schema,
        ifc_lines=lines,
        triples=len(store),
        turtle_bytes=store.turtle_size() if turtle else -1,
        elements=sum(per_class.values()),
        meshes=_count(store, f"?e a bot:Element ; omg:hasGeometry ?g {CURRENT}"),
        triangles=int(literal_value(tri_rows[0]["n"]) or 0) if tri_rows else 0,
        spaces=_count(store, "?s a bot:Space"),
        storeys=storeys,
        elements_per_class=per_class,
        mesh_failures=_count(store, "?e twin:meshFailed true"),
        failed_elements=tuple(
            literal_value(r["e"]) or ""
            for r in store.select("SELECT ?e WHERE { ?e twin:meshFailed true } ORDER BY ?e")
        ),
        kernel_fallbacks=_count(store, "?e twin:kernelFallback true"),
        removed=_count(store, "?e a bot:Element ; twin:removed true"),
        meshes_per_kernel={
            literal_value(r["k"]) or "": int(literal_value(r["n"]) or 0)
            for r in store.select(
                f"SELECT ?k (COUNT(?e) AS ?n) WHERE {{ ?e a bot:Element ; twin:meshKernel ?k {CURRENT} }} "
                "GROUP BY ?k ORDER BY ?k"
            )
        },
    )
