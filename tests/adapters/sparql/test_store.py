"""The GraphStore contract, run against the embedded store and a remote SPARQL server (a real
``oxigraph serve`` process), and what is particular to the embedded store."""

from __future__ import annotations

import io
import json
from collections.abc import Callable, Iterator
from pathlib import Path

import pyoxigraph as ox
import pytest

from adapters.sparql.remote_store import RemoteStore
from tests.sparql_server import SparqlServer
from twin.errors import QueryError, StoreError
from twin.graph import vocab
from twin.graph.rdf import ChangeSet, RdfLiteral, Triple
from twin.graph.store import EmbeddedStore

Q = ox.Quad(ox.NamedNode("https://ex.org/a"), ox.NamedNode("https://ex.org/p"), ox.Literal("x"))
EX = "https://ex.org/"
AnyStore = EmbeddedStore | RemoteStore
Opener = Callable[..., AnyStore]


@pytest.fixture(params=["embedded", "remote"])
def open_store(request: pytest.FixtureRequest) -> Iterator[Opener]:
    """Opens a fresh, empty store of each kind (``read_only=`` as the store's own open takes it)."""
    opened: list[AnyStore] = []
    if request.param == "embedded":

        def open_(*, read_only: bool = False) -> AnyStore:
            opened.append(EmbeddedStore.open(None, read_only=read_only))
            return opened[-1]
    else:
        server: SparqlServer = request.getfixturevalue("sparql_server")
        with RemoteStore.open(server.url) as admin:
            admin.clear()

        def open_(*, read_only: bool = False) -> AnyStore:
            opened.append(RemoteStore.open(server.url, read_only=read_only))
            return opened[-1]

    yield open_
    for store in opened:
        store.close()


@pytest.fixture
def store(open_store: Opener) -> AnyStore:
    return open_store()


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


def test_closing_twice_is_harmless_and_use_after_close_is_a_clear_error(store: AnyStore) -> None:
    store.close()
    store.close()
    with pytest.raises(StoreError, match="closed"):
        len(store)


def test_a_store_opened_read_only_refuses_every_write(open_store: Opener) -> None:
    store = open_store(read_only=True)
    for write in (
        lambda: store.add([Q]),
        lambda: store.bulk_add([Q]),
        lambda: store.apply(ChangeSet(add=(Triple(EX + "a", EX + "p", RdfLiteral("x")),))),
        store.clear,
    ):
        with pytest.raises(StoreError, match="read-only"):
            write()


def test_a_missing_store_is_not_created_for_reading(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="No store at"):
        EmbeddedStore.open(tmp_path / "none", read_only=True)
    assert not (tmp_path / "none").exists()


def test_a_query_that_does_not_parse_is_one_line_naming_where_and_what_was_expected() -> None:
    with EmbeddedStore.open(None) as store, pytest.raises(QueryError) as caught:
        store.select("SELECT ?e WHERE {\n  ?e ?p ?o")
    text = str(caught.value)
    assert "\n" not in text and "\\u{" not in text and "'0'" not in text  # no character classes
    where = "at line 2, column 11 (after '?e ?p ?o')"
    assert text.startswith(f"SPARQL query does not parse {where}: expected one of")
    assert text.endswith('"}", "~", a digit, a letter')


def test_queries_that_do_not_parse_and_updates_are_query_errors(store: AnyStore) -> None:
    with pytest.raises(QueryError, match=r"does not parse.*at (line )?1"):
        store.select("SELEKT ?s")
    with pytest.raises(QueryError, match="does not parse"):
        store.select("DELETE WHERE { ?s ?p ?o }")
    with pytest.raises(QueryError, match="SELECT"):
        store.select("ASK { ?s ?p ?o }")
    with pytest.raises(QueryError, match="ASK"):
        store.ask("SELECT ?s WHERE { ?s ?p ?o }")
    with pytest.raises(QueryError, match="SERVICE"):
        store.select("SELECT * WHERE { SERVICE <http://127.0.0.1:1/sparql> { ?s ?p ?o } }")


def test_serialized_results_are_sparql_json_or_turtle(store: AnyStore) -> None:
    store.add([Q])
    media, body = store.query_serialized("SELECT ?s WHERE { ?s ?p ?o }")
    assert media == "application/sparql-results+json"
    assert json.loads(body) == {
        "head": {"vars": ["s"]},
        "results": {"bindings": [{"s": {"type": "uri", "value": "https://ex.org/a"}}]},
    }
    media, body = store.query_serialized("ASK { ?s ?p ?o }")
    assert (media, json.loads(body)["boolean"]) == ("application/sparql-results+json", True)
    media, body = store.query_serialized("CONSTRUCT { ?s ?p ?o } WHERE { ?s ?p ?o }")
    assert media == "text/turtle"
    assert {q.triple for q in ox.parse(body, format=ox.RdfFormat.TURTLE)} == {Q.triple}


def _terms_sample() -> list[ox.Quad]:
    a, p, b = ox.NamedNode(EX + "a"), ox.NamedNode(EX + "p"), ox.BlankNode("b1")
    objects = [
        ox.Literal("x"),
        ox.Literal("chair", language="en"),
        ox.Literal("1.5", datatype=ox.NamedNode(vocab.XSD + "decimal")),
        ox.Literal("7", datatype=ox.NamedNode(vocab.XSD + "integer")),
        ox.Literal("true", datatype=ox.NamedNode(vocab.XSD_BOOLEAN)),
        ox.Literal("1 0 0 0", datatype=ox.NamedNode(vocab.TWIN_MATRIX4)),
        ox.Literal('quote " and \\ and\nnewline and ünïcødé'),
        ox.NamedNode(EX + "c"),
        b,
    ]
    return [ox.Quad(a, p, o) for o in objects] + [ox.Quad(b, p, ox.Literal("inner"))]


def test_rows_carry_the_lexical_value_of_every_kind_of_term(store: AnyStore) -> None:
    store.bulk_add(_terms_sample())
    rows = store.select(
        "SELECT ?o ?inner ?lang ?dt WHERE { <https://ex.org/a> ?p ?o "
        "OPTIONAL { ?o ?p ?inner } BIND(LANG(?o) AS ?lang) BIND(DATATYPE(?o) AS ?dt) }"
    )
    by_value = {r["o"]: r for r in rows}
    blank = [r for r in rows if r["inner"] == "inner"]
    assert len(rows) == 9 and len(blank) == 1
    label = blank[0]["o"]
    assert label and not label.startswith("_:")  # a blank node's label, as the embedded store gives it
    assert {k: v for k, v in by_value.items() if k != label} == {
        "x": {"o": "x", "inner": None, "lang": "", "dt": vocab.XSD + "string"},
        "chair": {"o": "chair", "inner": None, "lang": "en", "dt": vocab.RDF + "langString"},
        "1.5": {"o": "1.5", "inner": None, "lang": "", "dt": vocab.XSD + "decimal"},
        "7": {"o": "7", "inner": None, "lang": "", "dt": vocab.XSD + "integer"},
        "true": {"o": "true", "inner": None, "lang": "", "dt": vocab.XSD_BOOLEAN},
        "1 0 0 0": {"o": "1 0 0 0", "inner": None, "lang": "", "dt": vocab.TWIN_MATRIX4},
        'quote " and \\ and\nnewline and ünïcødé': {
            "o": 'quote " and \\ and\nnewline and ünïcødé',
            "inner": None,
            "lang": "",
            "dt": vocab.XSD + "string",
        },
        EX + "c": {"o": EX + "c", "inner": None, "lang": None, "dt": None},
    }
    assert store.ask('ASK { <https://ex.org/a> ?p ?o . ?o ?p "inner" }')  # one node, in both triples


def test_the_vocabulary_prefixes_are_predefined(store: AnyStore) -> None:
    store.apply(ChangeSet(add=(Triple(EX + "s", vocab.RDF_TYPE, vocab.BOT_STOREY),)))
    assert store.select("SELECT ?s WHERE { ?s a bot:Storey }") == [{"s": EX + "s"}]
    assert store.select("PREFIX bot: <https://ex.org/> SELECT ?s WHERE { ?s a bot:Storey }") == []


def test_apply_removes_the_patterns_then_adds_in_one_transaction(store: AnyStore) -> None:
    s, p, q = EX + "s", EX + "p", EX + "q"
    store.apply(ChangeSet(add=(Triple(s, p, RdfLiteral("1")), Triple(s, q, RdfLiteral("2")))))
    store.apply(ChangeSet(remove=((s, p),), add=(Triple(s, p, RdfLiteral("3")),)))
    assert sorted((r["p"], r["o"]) for r in store.select(f"SELECT ?p ?o WHERE {{ <{s}> ?p ?o }}")) == [
        (p, "3"),
        (q, "2"),
    ]
    store.apply(ChangeSet(remove=((s, None),)))
    assert store.is_empty() and len(store) == 0
    store.apply(ChangeSet())  # nothing to do
    with pytest.raises(StoreError, match="Not an IRI"):
        store.apply(ChangeSet(add=(Triple("has space", p, RdfLiteral("x")),)))


def test_an_update_that_fails_part_way_changes_nothing(store: AnyStore) -> None:
    with pytest.raises((StoreError, RuntimeError), match="already exists"):
        store.update("INSERT DATA { <urn:a> <urn:p> <urn:b> } ; CREATE GRAPH <urn:g> ; CREATE GRAPH <urn:g>")
    assert store.is_empty()


def test_bulk_add_len_clear_and_is_empty_agree(store: AnyStore) -> None:
    assert store.is_empty() and len(store) == 0
    many = [ox.Quad(ox.NamedNode(f"{EX}e{i}"), ox.NamedNode(EX + "n"), ox.Literal(i)) for i in range(25_000)]
    store.bulk_add(many)  # more than one streamed batch
    assert len(store) == 25_000 and not store.is_empty()
    assert store.select(f"SELECT ?n WHERE {{ <{EX}e24999> ?p ?n }}") == [{"n": "24999"}]
    store.clear()
    assert store.is_empty() and len(store) == 0


def test_the_turtle_dump_has_the_lbd_prefixes_and_every_triple(store: AnyStore, tmp_path: Path) -> None:
    quads = [q for q in _terms_sample() if not isinstance(q.subject, ox.BlankNode)]
    quads = [q for q in quads if not isinstance(q.object, ox.BlankNode)]
    quads.append(ox.Quad(ox.NamedNode(EX + "a"), ox.NamedNode(vocab.RDF_TYPE), ox.NamedNode(vocab.BOT_SPACE)))
    store.bulk_add(quads)
    buf = io.BytesIO()
    store.dump_turtle(buf)
    text = buf.getvalue()
    assert b"@prefix bot: <https://w3id.org/bot#> ." in text and b"bot:Space" in text
    assert {q.triple for q in ox.parse(text, format=ox.RdfFormat.TURTLE)} == {q.triple for q in quads}
    assert store.turtle_size() == len(text)
    store.dump_turtle(tmp_path / "out.ttl")
    assert (tmp_path / "out.ttl").read_bytes() == text


def test_both_stores_serialise_the_same_graph_to_the_same_bytes(sparql_server: SparqlServer) -> None:
    quads = [q for q in _terms_sample() if not isinstance(q.object, ox.BlankNode)]
    quads = [q for q in quads if not isinstance(q.subject, ox.BlankNode)]
    with EmbeddedStore.open(None) as embedded, RemoteStore.open(sparql_server.url) as remote:
        remote.clear()
        embedded.bulk_add(quads)
        remote.bulk_add(quads)
        select = "SELECT ?p ?o WHERE { ?s ?p ?o } ORDER BY ?o"
        assert remote.query_serialized(select) == embedded.query_serialized(select)
        assert remote.select(select) == embedded.select(select)
        assert remote.turtle_size() == embedded.turtle_size()


def test_text_with_an_unchecked_bad_iri_is_refused_naming_where_and_checked_text_loads() -> None:
    good = b'<https://example.org/a> <https://example.org/p> "x" .\n'
    bad = b'<https://example.org/a b> <https://example.org/p> "x" .\n'
    with EmbeddedStore.open(None) as store:
        with pytest.raises(StoreError, match=r"do not parse: .*line 2 .*Invalid IRI code point ' '"):
            store.bulk_load_ntriples(good + bad)
        store.bulk_load_ntriples(good, iris_checked=True)
        assert len(store) == 1
