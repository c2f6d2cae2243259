"""Import a building model into the graph store (the paper's Algorithm 1, records -> triples).

Every storey, space and element becomes a node with an IFCtoLBD IRI; spaces are ``bot:adjacentElement``
to the elements bounding them and ``bot:containsElement`` the elements they contain; elements carry
their class (BOT + BEO/FURN + the IFC class), GlobalId, name, materials, ``twin:isStatic`` and, through
``omg:hasGeometry``, their local mesh (a FOG PLY literal) and 4x4 placement.

Example::

    model = adapters.ifc.read_model(Path("lab.ifc"))
    with EmbeddedStore.open(Path("lab.store")) as store:
        summary = import_model(store, model, base_iri="https://example.org/lab#", site="lab")
"""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Final

from twin import vocab
from twin.errors import StoreNotEmptyError
from twin.gc_pause import paused_gc
from twin.model_triples import ModelTriples, checked_iris, geometry_triples, structure_triples
from twin.records import BuildingModel
from twin.store import GraphStore, TextLoader

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class ImportSummary:
    triples: int
    elements: int
    meshes: int
    spaces: int
    storeys: int
    mesh_failures: tuple[str, ...]
    kernel_fallbacks: tuple[str, ...]


_MIN_PART: Final = 5_000  # triples: below this a second bulk load costs more than it saves


def _load(store: GraphStore, triples: ModelTriples, source: str) -> None:
    if isinstance(store, TextLoader) and not triples.meshes:
        store.bulk_load_ntriples(triples.data(source))
    else:
        store.bulk_add(triples.quads(source))


def _split(triples: ModelTriples, store: GraphStore) -> list[ModelTriples]:
    """``triples`` (text only) in parts that load side by side: the store's bulk loader runs one thread
    per call, so a store that loads text gets two halves (on 2 cores, half the time for 250,000
    triples); a store that takes quads gets one part."""
    if not isinstance(store, TextLoader) or len(triples.lines) < 2 * _MIN_PART:
        return [triples]
    half = len(triples.lines) // 2
    parts = [ModelTriples(), ModelTriples()]
    parts[0].lines, parts[1].lines = triples.lines[:half], triples.lines[half:]
    return parts


def ensure_importable(store: GraphStore, *, replace: bool) -> None:
    """Raise StoreNotEmptyError if ``store`` holds a model and ``replace`` is unset (check before meshing)."""
    if not replace and not store.is_empty():
        msg = "The store already holds a model."
        raise StoreNotEmptyError(msg)


@paused_gc()  # few cycles are made: see twin.gc_pause
def import_model(
    store: GraphStore, model: BuildingModel, *, base_iri: str, site: str, replace: bool = False
) -> ImportSummary:
    """Write ``model`` into ``store``. A non-empty store is an error unless ``replace`` is set."""
    ensure_importable(store, replace=replace)
    base_iri = vocab.check_base(base_iri)
    iri_of = checked_iris(model, base_iri)
    structure = structure_triples(model, iri_of, base_iri=base_iri, site=site)
    if replace:  # every check passes before the old graph goes
        geometry = geometry_triples(model, iri_of)
        store.clear()
        _load(store, structure, model.source_name)
    else:
        # The store loads the structure (no GIL held while it parses text) while this thread builds
        # the geometry part; if building it fails, the store is emptied again.
        parts = _split(structure, store)
        with ThreadPoolExecutor(len(parts), thread_name_prefix="twin-import") as pool:
            loading = [pool.submit(_load, store, part, model.source_name) for part in parts]
            try:
                geometry = geometry_triples(model, iri_of)
            except BaseException:
                wait(loading)
                store.clear()
                raise
            for done in loading:
                done.result()
    _load(store, geometry, model.source_name)
    meshes = sum(1 for e in model.elements if e.geometry is not None)
    if model.mesh_failures:
        log.info(
            "%d element(s) are in the graph without geometry (twin:meshFailed)", len(model.mesh_failures)
        )
    return ImportSummary(
        triples=len(store),
        elements=len(model.elements),
        meshes=meshes,
        spaces=len(model.spaces),
        storeys=len(model.storeys),
        mesh_failures=model.mesh_failures,
        kernel_fallbacks=model.kernel_fallbacks,
    )
