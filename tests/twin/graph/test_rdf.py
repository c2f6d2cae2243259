"""Change sets as SPARQL text: literals and IRIs written as pyoxigraph writes them, bad IRIs refused."""

from __future__ import annotations

import pyoxigraph as ox
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import examples
from twin.errors import StoreError
from twin.graph import vocab
from twin.graph.rdf import ChangeSet, RdfLiteral, Triple, changes_to_sparql

DATATYPES = [vocab.XSD_STRING, vocab.XSD_INTEGER, vocab.XSD_DATETIME, vocab.TWIN_MATRIX4, vocab.XSD_BOOLEAN]


@settings(max_examples=examples(300), deadline=None)
@given(
    value=st.text(alphabet=st.sampled_from('ab 1.-:"\\\n\r\t\x00\x7f\x1f é€😀<>{}^`|'), max_size=12),
    datatype=st.sampled_from(DATATYPES),
)
def test_a_literal_is_written_as_pyoxigraph_writes_it_whatever_it_holds(value: str, datatype: str) -> None:
    update = changes_to_sparql(ChangeSet(add=(Triple("urn:s", "urn:p", RdfLiteral(value, datatype)),)))
    want = str(ox.Literal(value, datatype=ox.NamedNode(datatype)))
    assert update == f"INSERT DATA {{\n<urn:s> <urn:p> {want} .\n}}"
    store, theirs = ox.Store(), ox.Store()  # the store may canonicalise a value ("1" as boolean: true)
    store.update(update)
    theirs.update(f"INSERT DATA {{ <urn:s> <urn:p> {want} . }}")
    assert [q.object for q in store] == [q.object for q in theirs]


BAD_IRIS = ["", "urn:a b", "urn:a<b", "urn:x\n", "urn:a\\b", "urn:a^b", "urn:{a}", 'urn:"']


@pytest.mark.parametrize("iri", BAD_IRIS)
def test_an_iri_a_change_cannot_hold_is_refused_by_name(iri: str) -> None:
    with pytest.raises(StoreError, match="Not an IRI usable in a change"):
        changes_to_sparql(ChangeSet(add=(Triple("urn:s", "urn:p", iri),)))
