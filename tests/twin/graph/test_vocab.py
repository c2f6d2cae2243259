from __future__ import annotations

import ifcopenshell.guid
import pytest
from hypothesis import given
from hypothesis import strategies as st

from twin.errors import ModelError
from twin.graph import vocab


@given(st.uuids())
def test_guid_expansion_matches_ifcopenshell_and_round_trips(u) -> None:
    compressed = ifcopenshell.guid.compress(u.hex)
    assert vocab.expand_guid(compressed) == str(u)
    assert vocab.compress_guid(str(u)) == compressed


def test_an_invalid_guid_is_rejected_naming_it() -> None:
    with pytest.raises(ModelError, match="'not-a-guid'"):
        vocab.expand_guid("not-a-guid")


_GUID_LIKE = st.text(
    alphabet="0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$4 #\n-é", max_size=23
)


@given(st.one_of(_GUID_LIKE, st.from_regex(r"[0-3][0-9A-Za-z_$]{21}", fullmatch=True)))
def test_a_guid_expands_to_its_value_digit_by_digit_or_is_rejected(guid: str) -> None:
    digits = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$"
    if len(guid) == 22 and guid[0] in "0123" and all(c in digits for c in guid):
        value = 0
        for c in guid:
            value = value * 64 + digits.index(c)
        h = f"{value:032x}"
        assert vocab.expand_guid(guid) == f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:]}"
    else:
        with pytest.raises(ModelError, match="Not an IFC GlobalId"):
            vocab.expand_guid(guid)


def test_element_iri_is_ifctolbd_style() -> None:
    iri = vocab.entity_iri("https://ex.org/b#", "IfcWallStandardCase", "0" * 22)
    assert iri == "https://ex.org/b#wallstandardcase_00000000-0000-0000-0000-000000000000"


def test_semantic_classes_map_walls_to_beo_and_furniture_to_furn() -> None:
    assert vocab.semantic_class("IfcWallStandardCase") == vocab.BEO + "Wall"
    assert vocab.semantic_class("IfcFurnishingElement") == vocab.FURN + "Furniture"
    assert vocab.semantic_class("IfcFlowTerminal") is None


def test_storey_keys_are_safe_and_unique() -> None:
    used: set[str] = set()
    assert vocab.storey_key("1. Obergeschoss", used) == "1-obergeschoss"
    assert vocab.storey_key("1 Obergeschoss", used) == "1-obergeschoss-2"
    assert vocab.storey_key("Floor Plan_1st Floor") == "floor-plan-1st-floor"


@pytest.mark.parametrize("base", ["example.org/x#", "https://ex.org/x", "https://ex.org/a b#"])
def test_a_bad_base_iri_is_rejected(base: str) -> None:
    with pytest.raises(ModelError, match="Base IRI"):
        vocab.check_base(base)


@pytest.mark.parametrize(
    ("file_name", "site"),
    [
        ("revit2012_janesville_restaurant.ifc", "revit2012-janesville-restaurant"),
        ("AC20-FZK-Haus.ifc", "ac20-fzk-haus"),
        ("Duplex_A_20110907.ifc", "duplex-a-20110907"),
        ("lab.ifc", "lab"),
        ("/some/dir/Büro Nord (v2).IFC", "b-ro-nord-v2"),
        ("___.ifc", "site"),
        ("x" * 100 + ".ifc", "x" * 64),
    ],
)
def test_a_site_is_named_after_its_file_in_lower_case_letters_digits_and_dashes(
    file_name: str, site: str
) -> None:
    assert vocab.site_slug(file_name) == site
