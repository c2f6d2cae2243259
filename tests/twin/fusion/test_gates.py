"""The gates association, merge and absence share: size and kind."""

from __future__ import annotations

from twin.config import FusionRules
from twin.fusion.footprints import box_pose
from twin.fusion.gates import descriptive_types, kinds_agree, lies_within, sizes_agree
from twin.live.state import ElementState

RULES = FusionRules().default
FURN = "http://pi.pauwel.be/voc/furniture#"
BOT_ELEMENT = "https://w3id.org/bot#Element"


def test_a_box_within_35_percent_on_each_side_agrees_in_size_and_a_chair_against_a_table_does_not() -> None:
    table = box_pose(0, 0, 0.375, 1.2, 0.8, 0.75, yaw=0.0)
    assert sizes_agree(RULES, box_pose(0.1, 0, 0.4, 1.3, 0.7, 0.8, yaw=0.1), table)
    assert not sizes_agree(RULES, box_pose(0.3, 0, 0.45, 0.55, 0.55, 0.9, yaw=0.0), table)
    assert not sizes_agree(RULES, box_pose(0.6, 0, 0.375, 2.4, 0.8, 0.75, yaw=0.0), table)


def test_the_footprint_area_ratio_is_a_gate_of_its_own() -> None:
    held = box_pose(0, 0, 0.5, 1.0, 1.0, 1.0, yaw=0.0)
    seen = box_pose(0, 0, 0.5, 0.7, 0.67, 1.0, yaw=0.0)  # each side within 35 %, area 0.47 of it
    assert not sizes_agree(RULES, seen, held)


def test_a_smaller_box_inside_a_footprint_lies_within_it_and_one_sticking_out_does_not() -> None:
    table = box_pose(0, 0, 0.375, 1.2, 0.8, 0.75, yaw=0.3)
    assert lies_within(box_pose(0.2, 0.1, 0.4, 0.5, 0.5, 0.9, yaw=0.3), table, margin_m=0.05)
    assert not lies_within(box_pose(0.6, 0.1, 0.4, 0.5, 0.5, 0.9, yaw=0.3), table, margin_m=0.05)


def test_kinds_agree_when_either_side_has_no_descriptive_type_and_differ_when_both_have_other_ones() -> None:
    table = ElementState(
        "urn:t",
        "IfcFurniture",
        ("IfcFurniture", "IfcFurnishingElement", "IfcElement"),
        is_static=False,
        classes=frozenset({BOT_ELEMENT, FURN + "Furniture", FURN + "Table"}),
    )
    assert descriptive_types("IFC4", table.classes, table.ifc_class) == {FURN + "Table"}
    assert kinds_agree("IFC4", (), "IfcFurniture", table)
    assert kinds_agree("IFC4", (FURN + "Furniture",), "IfcFurniture", table)
    assert kinds_agree("IFC4", (FURN + "Table",), None, table)
    assert not kinds_agree("IFC4", (FURN + "Chair",), "IfcFurniture", table)
