"""The batch's view of the twin (``Layered``) reads exactly as the ``ChainMap`` it replaces."""

from __future__ import annotations

from collections import ChainMap

from hypothesis import given
from hypothesis import strategies as st

from twin.live.layered import Layered

_dicts = st.dictionaries(st.sampled_from("abcdefgh"), st.integers(0, 5), max_size=6)


@given(_dicts, _dicts, st.sampled_from("abcdefghz"))
def test_a_layered_view_reads_as_a_chain_map(top: dict[str, int], base: dict[str, int], key: str) -> None:
    chain, layered = ChainMap(top, base), Layered(top, base)
    assert list(layered) == list(chain)
    assert len(layered) == len(chain)
    assert dict(layered.items()) == dict(chain.items())
    assert (key in layered) == (key in chain)
    assert layered.get(key) == chain.get(key)
    assert layered.get(key, -1) == chain.get(key, -1)
    if key in chain:
        assert layered[key] == chain[key]


def test_a_key_of_the_top_hides_the_base_even_when_its_value_is_none() -> None:
    layered = Layered({"a": None}, {"a": 1})
    assert layered.get("a", 7) is None
    assert layered["a"] is None
    assert "a" in layered
