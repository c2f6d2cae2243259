from __future__ import annotations

from pathlib import Path

import pyoxigraph as ox
import pytest

from twin.errors import QueryError, StoreError
from twin.store import EmbeddedStore

Q = ox.Quad(ox.NamedNode("https://ex.org/a"), ox.NamedNode("https://ex.org/p"), ox.Literal("x"))


def test_an_on_disk_store_keeps_its_triples_across_opens(tmp_path: Path) -> None:
    with EmbeddedStore.open(tmp_path / "s") as store:
        store.add([Q])
    with EmbeddedStore.open(tmp_path / "s", read_only=True) as again:
        assert len(again) == 1


def test_a_read_only_store_refuses_writes(tmp_path: Path) -> None:
    EmbeddedStore.open(tmp_path / "s").close()
    with (
        EmbeddedStore.open(tmp_path / "s", read_only=True) as store,
        pytest.raises(StoreError, match="read-only"),
    ):
        store.add([Q])
    with EmbeddedStore.open(None, read_only=True) as mem, pytest.raises(StoreError, match="read-only"):
        mem.add([Q])


def test_closing_twice_is_harmless_and_use_after_close_is_a_clear_error() -> None:
    store = EmbeddedStore.open(None)
    store.close()
    store.close()
    with pytest.raises(StoreError, match="closed"):
        len(store)


def test_a_missing_store_is_not_created_for_reading(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="No store at"):
        EmbeddedStore.open(tmp_path / "none", read_only=True)
    assert not (tmp_path / "none").exists()


def test_queries_that_do_not_parse_and_updates_are_query_errors() -> None:
    with EmbeddedStore.open(None) as store:
        with pytest.raises(QueryError, match="does not parse"):
            store.select("SELEKT ?s")
        with pytest.raises(QueryError, match="does not parse"):
            store.select("DELETE WHERE { ?s ?p ?o }")
        with pytest.raises(QueryError, match="SELECT"):
            store.select("ASK { ?s ?p ?o }")


def test_serialized_results_are_sparql_json_or_turtle() -> None:
    with EmbeddedStore.open(None) as store:
        store.add([Q])
        media, body = store.query_serialized("SELECT ?s WHERE { ?s ?p ?o }")
        assert media == "application/sparql-results+json"
        assert b"https://ex.org/a" in body
        media, body = store.query_serialized("CONSTRUCT { ?s ?p ?o } WHERE { ?s ?p ?o }")
        assert media == "text/turtle"
        assert b"https://ex.org/a" in body
