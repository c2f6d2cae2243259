"""Forgetting tombstones: a removed element is kept only as long as its tombstone serves a purpose.

A removed element stays as a tombstone (``twin:removed true`` with its removal's sense time and
provenance, no geometry) so that a sighting sensed before the removal that arrives later does not bring
it back (:func:`~twin.fusion.clocks.stale_tombstone`), and so that the graph says when and by whom it
was removed. Robots mint new IRIs all day (Open-RMF obstacles that expire, objects removed by absence),
so kept forever the tombstones would grow the writer's memory and the graph without bound.

The writer forgets a tombstone once its removal's sense time (on the daemon's clock, the one the stale
check compares with) is more than ``[fusion] tombstone_ttl_s`` old: everything it holds of the element
(its state, held triples, last sighting, fusion's history, pose caches, the aliases that name it) and
every triple of it in the graph (its own and those that point to it: the storey's
``bot:containsElement``, aliases; a merged element's IRI stays an alias of the element kept, until it
expires as aliases do), in one store transaction per pass and at most
:data:`FORGET_BATCH` elements a pass (those one walk of the states found due are worked off over the
next passes before the states are walked again). Elements imported from the IFC model keep their
tombstones (the building bounds their number, and the graph keeps the record that the model's element
is gone). A report of a forgotten IRI with a class creates a new element, as after any removal.

Example::

    due = due_tombstones(live, now_ns=clock(), ttl_ns=rules.tombstone_ttl_ns, base_iri=base_iri)
    store.apply(forget_changes(store, live, due[:FORGET_BATCH]))
    forget_elements(live, due[:FORGET_BATCH])
"""

from __future__ import annotations

from collections.abc import Sequence

from twin.fusion import confirm_array
from twin.graph import vocab
from twin.graph.rdf import ChangeSet, Triple
from twin.graph.store import GraphStore
from twin.live.state import LiveState

FORGET_BATCH = 200
"""Tombstones forgotten in one pass at most (one store transaction, about 0.2 ms each on an on-disk
store): a backlog of thousands (a first start with a short ``tombstone_ttl_s`` on an old graph) is
worked off over several passes, between which the writer serves its queue."""


def due_tombstones(live: LiveState, *, now_ns: int, ttl_ns: int, base_iri: str) -> list[str]:
    """The removed elements (not imported from the model: ``base_iri``) whose removal was sensed more
    than ``ttl_ns`` before ``now_ns``, oldest first; none when ``ttl_ns`` is 0."""
    if ttl_ns <= 0:
        return []
    due = [
        (state.sensed_ns, iri)
        for iri, state in live.states.items()
        if state.removed and now_ns - state.sensed_ns > ttl_ns and not (base_iri and iri.startswith(base_iri))
    ]
    due.sort()
    return [iri for _, iri in due]


def still_due(live: LiveState, iri: str, *, now_ns: int, ttl_ns: int) -> bool:
    """Whether ``iri``, found due earlier, still is (not created again since)."""
    state = live.states.get(iri)
    return state is not None and state.removed and now_ns - state.sensed_ns > ttl_ns > 0


def forget_changes(store: GraphStore, live: LiveState, iris: Sequence[str]) -> ChangeSet:
    """Every triple of ``iris`` in the graph: their own (and their geometry nodes'), and those that
    point to them (exact deletes, found with one query); but an IRI that is itself an alias (a merged
    element's: it resolves to the element kept) keeps its ``twin:aliasOf``, which expires as aliases do."""
    if not iris:
        return ChangeSet()
    values = " ".join(f"<{i}>" for i in iris)
    rows = store.select(f"SELECT ?s ?p ?e WHERE {{ VALUES ?e {{ {values} }} ?s ?p ?e FILTER(isIRI(?s)) }}")
    incoming = tuple(Triple(r["s"] or "", r["p"] or "", r["e"] or "") for r in rows)
    own = tuple((s, None) for i in iris for s in (i, vocab.geometry_iri(i)))
    aliases = live.fusion.aliases
    kept = tuple(Triple(i, vocab.TWIN_ALIAS_OF, aliases[i].target) for i in iris if i in aliases)
    return ChangeSet(remove=own, delete=incoming, add=kept)


def forget_elements(live: LiveState, iris: Sequence[str]) -> None:
    """Forget everything the writer holds of ``iris`` (tombstones): their states, held triples, last
    sightings, fusion's memory of them and the aliases that name them (the graph's triples are the
    caller's: :func:`forget_changes`)."""
    memory = live.fusion
    for iri in iris:
        live.states.pop(iri, None)
        live.held.pop(iri, None)
        live.held.pop(vocab.geometry_iri(iri), None)
        live.last_seen.pop(iri, None)
        memory.tracks.pop(iri, None)
        memory.history.pop(iri, None)
        memory.shape_poses.pop(iri, None)
        memory.tentative.pop(iri, None)
        memory.distinct.discard(iri)
    gone = set(iris)
    for alias in [a for a, v in memory.aliases.items() if v.target in gone]:
        del memory.aliases[alias]
        live.last_seen.pop(alias, None)
    if memory.poses is not None:
        for storey, poses in memory.poses.items():
            if any([poses.pop(iri, None) is not None for iri in iris]):
                memory.pose_arrays.pop(storey, None)
    confirm_array.forget(memory, iris)


def forget_restored(store: GraphStore, live: LiveState, base_iri: str) -> list[str]:
    """After a start from a snapshot: forget the tombstones the snapshot holds that the graph no longer
    does (forgotten after the snapshot was taken), and fusion's history of elements the twin does not
    hold, so that a restart never brings a forgotten tombstone back. Returns the IRIs forgotten."""
    kept = {r["e"] or "" for r in store.select("SELECT ?e WHERE { ?e twin:removed true }")}
    gone = [
        iri
        for iri, state in live.states.items()
        if state.removed and iri not in kept and not (base_iri and iri.startswith(base_iri))
    ]
    forget_elements(live, gone)
    history = live.fusion.history
    for iri in [i for i in history if i not in live.states]:
        del history[iri]
    return gone
