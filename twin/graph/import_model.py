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
import threading
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from types import TracebackType
from typing import Final, Self

from twin.errors import ModelError, StoreNotEmptyError
from twin.gc_pause import paused_gc
from twin.graph import vocab
from twin.graph.extents import geometry_bounds
from twin.graph.model_triples import (
    MeshLiterals,
    ModelTriples,
    checked_iris,
    geometry_nodes,
    geometry_triples,
    structure_triples,
)
from twin.graph.store import GraphStore, TextLoader
from twin.records import BuildingModel, FloatArray, Geometry

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
_PART_TRIANGLES: Final = 100_000  # geometry written while meshing goes on: a bulk load per this many
_PART_NODES: Final = 5_000  # triangles of meshes not written before (an instance's costs little) or nodes


def _load(store: GraphStore, triples: ModelTriples, source: str, quads_lock: threading.Lock) -> None:
    """Load ``triples``: the lines as text when the store parses text (without the GIL; their IRIs
    were checked when they were made, :func:`checked_iris`) and the mesh literals kept as objects as
    quads, else all as quads. Loads of quads go one at a time (``quads_lock``): two of them at once can
    deadlock, each holding what the other needs (the store's bulk loader, the GIL to read its quads).
    A load of text needs no GIL, so it may run beside a load of quads."""
    if isinstance(store, TextLoader):
        store.bulk_load_ntriples(triples.data(source), iris_checked=True)
        for quads in triples.mesh_quads():
            with quads_lock:
                store.bulk_add(quads)
    else:
        with quads_lock:
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


class ModelImport:
    """An import in two steps, so that the store loads the structure while the geometry is being made.

    :meth:`write_structure` takes the model without geometry (every ``geometry`` None) and starts loading
    its triples (the store parses text without the GIL); :meth:`finish` takes the same model with its
    geometry and writes the rest. Leaving the context on an error empties the store again. With
    ``replace``, nothing is written before every triple is made: the old graph stays if a check fails.

    Example::

        with ModelImport(store, base_iri="https://example.org/lab#", site="lab") as job:
            job.write_structure(reading.structure())
            summary = job.finish(reading.model())
    """

    def __init__(self, store: GraphStore, *, base_iri: str, site: str, replace: bool = False) -> None:
        ensure_importable(store, replace=replace)
        self._store = store
        self._base_iri = vocab.check_base(base_iri)
        self._site = site
        self._replace = replace
        self._pool = ThreadPoolExecutor(2, thread_name_prefix="twin-import")
        self._quads_lock = threading.Lock()
        self._loading: list[Future[None]] = []
        self._structure: ModelTriples | None = None
        self._guids: tuple[str, ...] = ()
        self._iri_of: dict[str, str] = {}
        self._source = ""
        self._wrote = False
        self._literals = MeshLiterals()  # each mesh's literal, encoded once for every part
        self._written: dict[str, Geometry] = {}  # GlobalId -> the geometry written by add_geometry
        self._part_items: list[tuple[str, Geometry, str]] = []  # geometry nodes for the next part
        self._part_guids: list[str] = []
        self._bounds: dict[str, FloatArray] = {}  # GlobalId -> the box of its written geometry
        self._part_triangles = 0
        self._meshes_seen: set[int] = set()  # id() of the meshes added (each kept by _written)

    def write_structure(self, model: BuildingModel) -> None:
        """Make the triples that need no geometry and (unless replacing) start loading them."""
        self._iri_of = checked_iris(model, self._base_iri)
        self._guids = tuple(e.guid for e in model.elements)
        self._source = model.source_name
        structure = structure_triples(model, self._iri_of, base_iri=self._base_iri, site=self._site)
        if self._replace:  # loaded in finish(), once every check has passed
            self._structure = structure
            return
        self._wrote = True
        self._loading = [
            self._pool.submit(_load, self._store, part, self._source, self._quads_lock)
            for part in _split(structure, self._store)
        ]

    def add_geometry(self, guid: str, geometry: Geometry, kernel: str) -> None:
        """Write the geometry node of one element or space (``kernel`` "" for a space) now, in parts
        loaded in the background (after :meth:`write_structure`; nothing before :meth:`finish` when
        replacing). :meth:`finish` checks that the model's geometry is this one."""
        if self._replace:
            return
        node = self._iri_of.get(guid)
        if node is None:
            msg = f"{self._source}: no element or space {guid!r} in the structure written."
            raise ModelError(msg)
        self._part_items.append((node, geometry, kernel))
        self._part_guids.append(guid)
        self._written[guid] = geometry
        if id(geometry.mesh) not in self._meshes_seen:
            self._meshes_seen.add(id(geometry.mesh))
            self._part_triangles += geometry.mesh.triangle_count
        if self._part_triangles >= _PART_TRIANGLES or len(self._part_items) >= _PART_NODES:
            self._flush_part()

    def _flush_part(self) -> None:
        """Load the geometry nodes added since the last part (all text, parsed without the GIL), and
        work out their boxes for the storey extents meanwhile."""
        if self._part_items:
            part = ModelTriples(self._literals, meshes_as_text=True)
            geometry_nodes(part, self._part_items)
            self._loading.append(self._pool.submit(_load, self._store, part, self._source, self._quads_lock))
            geometries = [g for _, g, _ in self._part_items]
            self._bounds.update(geometry_bounds(list(zip(self._part_guids, geometries, strict=True))))
        self._part_items, self._part_guids, self._part_triangles = [], [], 0

    def finish(self, model: BuildingModel) -> ImportSummary:
        """Write the geometry of ``model`` (the model given to :meth:`write_structure`, with its meshes);
        wait for every load; the import's summary."""
        if tuple(e.guid for e in model.elements) != self._guids or model.source_name != self._source:
            msg = f"{model.source_name}: the model to finish is not the one whose structure was written."
            raise ModelError(msg)
        self._flush_part()
        geometry = geometry_triples(model, self._iri_of, written=self._written, bounds=self._bounds)
        if self._replace and self._structure is not None:
            self._store.clear()
            self._wrote = True
            _load(self._store, self._structure, self._source, self._quads_lock)
        for done in self._loading:
            done.result()
        _load(self._store, geometry, self._source, self._quads_lock)
        if model.mesh_failures:
            log.info(
                "%d element(s) are in the graph without geometry (twin:meshFailed)", len(model.mesh_failures)
            )
        return ImportSummary(
            triples=len(self._store),
            elements=len(model.elements),
            meshes=sum(1 for e in model.elements if e.geometry is not None),
            spaces=len(model.spaces),
            storeys=len(model.storeys),
            mesh_failures=model.mesh_failures,
            kernel_fallbacks=model.kernel_fallbacks,
        )

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        wait(self._loading)
        self._pool.shutdown()
        if exc is not None and self._wrote:
            self._store.clear()


@paused_gc()  # the import makes few cycles; collecting costs ~0.2 s on 12,000 elements
def import_model(
    store: GraphStore, model: BuildingModel, *, base_iri: str, site: str, replace: bool = False
) -> ImportSummary:
    """Write ``model`` into ``store``. A non-empty store is an error unless ``replace`` is set."""
    with ModelImport(store, base_iri=base_iri, site=site, replace=replace) as job:
        job.write_structure(model)
        return job.finish(model)
