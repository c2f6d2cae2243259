"""``[fusion]``: how observations from many robots become one twin (association, confirmation,
absence, sense time). See docs/fusion.md.

Example::

    [fusion]
    confirm_distance_m = 0.15          # a sighting this close to the held pose confirms it
    [fusion.classes.IfcChair]           # per IFC class (subtypes included), any key of the table
    confirm_distance_m = 0.10
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import Field

from twin.config.base import ConfigTable, Flag, Number, Whole


class FusionClassTable(ConfigTable):
    """``[fusion.classes.<IfcClass>]``: the per-class values that differ from ``[fusion]``'s."""

    confirm_distance_m: Annotated[Number, Field(ge=0.0, le=10.0)] | None = None
    confirm_angle_deg: Annotated[Number, Field(ge=0.0, le=180.0)] | None = None
    min_iou: Annotated[Number, Field(gt=0.0, le=1.0)] | None = None
    small_object_m: Annotated[Number, Field(ge=0.0, le=10.0)] | None = None
    centre_distance_m: Annotated[Number, Field(ge=0.0, le=10.0)] | None = None
    misses_to_remove: Annotated[Whole, Field(ge=1, le=1000)] | None = None
    miss_span_s: Annotated[Number, Field(ge=0.0, le=86400.0)] | None = None
    ttl_s: Annotated[Number, Field(ge=0.0)] | None = None
    size_ratio: Annotated[Number, Field(ge=0.0, le=10.0)] | None = None
    min_area_ratio: Annotated[Number, Field(ge=0.0, le=1.0)] | None = None


class FusionTable(ConfigTable):
    """``[fusion]``: many robots, one twin."""

    enabled: Flag = Field(
        True, description="Associate, confirm and remove by absence (false: as robots say)."
    )
    confirm_distance_m: Annotated[Number, Field(ge=0.0, le=10.0)] = Field(
        0.15, description="A sighting whose centre is this close (x, y and z) to the held pose confirms it."
    )
    confirm_angle_deg: Annotated[Number, Field(ge=0.0, le=180.0)] = Field(
        10.0, description="... and whose yaw is this close (modulo the footprint's symmetry), degrees."
    )
    refine_after: Annotated[Whole, Field(ge=1, le=100000)] = Field(
        10, description="Confirmations averaged in memory before a refined pose may be committed."
    )
    refine_fraction: Annotated[Number, Field(gt=0.0, le=1.0)] = Field(
        0.5,
        description="The mean of the confirmations is committed once it is this fraction of the "
        "confirmation distance (or angle) from the held pose (hysteresis: a still object does not flap).",
    )
    refine_distance_m: Annotated[Number, Field(ge=0.0, le=10.0)] = Field(
        0.05,
        description="... or once its centre is this far from the held pose (a map cell: a pose a cell off "
        "shows free floor inside the object).",
    )
    move_sightings: Annotated[Whole, Field(ge=1, le=100)] = Field(
        2,
        description="Sightings that must agree before a move shorter than certain_move_m is applied "
        "(a detector's outlier is not a move; 1: every sighting beyond the confirmation distance moves).",
    )
    certain_move_m: Annotated[Number, Field(ge=0.0, le=100.0)] = Field(
        0.5, description="A sighting this far from the held pose moves the element at once."
    )
    disagreement_window_s: Annotated[Number, Field(ge=0.0, le=86400.0)] = Field(
        10.0,
        description="A short move is held while another robot confirmed the held pose within this long, "
        "unless a second robot agrees with it (two biased detectors do not flap a still object).",
    )
    resize_sightings: Annotated[Whole, Field(ge=1, le=1000)] = Field(
        5,
        description="A robot-made box element takes other sizes only when two robots agree on them, or "
        "one robot over this many sightings spanning resize_span_s (an element imported from IFC keeps "
        "its mesh).",
    )
    resize_span_s: Annotated[Number, Field(ge=0.0, le=3600.0)] = Field(
        1.0, description="... spanning at least this long (sense time)."
    )
    min_iou: Annotated[Number, Field(gt=0.0, le=1.0)] = Field(
        0.25,
        description="A new robot IRI is an existing element if their footprints overlap this much (IoU).",
    )
    small_object_m: Annotated[Number, Field(ge=0.0, le=10.0)] = Field(
        0.6, description="Footprints whose longer side is below this are matched by centre distance."
    )
    centre_distance_m: Annotated[Number, Field(ge=0.0, le=10.0)] = Field(
        0.3, description="The centre distance that matches small objects, metres."
    )
    size_ratio: Annotated[Number, Field(ge=0.0, le=10.0)] = Field(
        0.35,
        description="A box is the element only if each horizontal side and the height differ from the "
        "element's by at most this fraction of the element's (0.35: 35 %).",
    )
    min_area_ratio: Annotated[Number, Field(ge=0.0, le=1.0)] = Field(
        0.5, description="... and the smaller footprint area is at least this fraction of the larger."
    )
    merge_iou: Annotated[Number, Field(gt=0.0, le=1.0)] = Field(
        0.5, description="Two elements whose footprints overlap this much after a change are merged."
    )
    tentative_sightings: Annotated[Whole, Field(ge=1, le=100)] = Field(
        1, description="Sightings a new element needs before it is created (1: at once)."
    )
    stream_sightings: Annotated[Whole, Field(ge=1, le=100)] = Field(
        2,
        description="A robot that streams views (its previous view was seen within stream_gap_s): the "
        "sightings in a row a new object it reports with a view needs before it is created; its next view "
        "that should have seen it without it drops it (a false detection). 1: at once.",
    )
    stream_gap_s: Annotated[Number, Field(ge=0.0, le=3600.0)] = Field(
        2.0,
        description="A robot whose previous view was seen at most this long before (sense time) streams "
        "(a one-shot report with a view creates at once).",
    )
    misses_to_remove: Annotated[Whole, Field(ge=1, le=1000)] = Field(
        3, description="Views that should have seen an element and did not, before it is removed."
    )
    miss_span_s: Annotated[Number, Field(ge=0.0, le=86400.0)] = Field(
        1.0, description="... spread over at least this long (sense time), with no sighting in between."
    )
    ttl_s: Annotated[Number, Field(ge=0.0)] = Field(
        0.0, description="Remove robot-added elements nobody confirmed for this long (0: never)."
    )
    alias_jump_m: Annotated[Number, Field(gt=0.0, le=1000.0)] = Field(
        2.0,
        description="A report through an alias farther than this from the element (or failing the size "
        "and kind gates) drops the alias and is associated afresh (a reused tracker id is a new object).",
    )
    alias_ttl_s: Annotated[Number, Field(gt=0.0)] = Field(
        3600.0, description="A robot IRI that resolved to an element is forgotten when unused this long."
    )
    tombstone_ttl_s: Annotated[Number, Field(ge=0.0)] = Field(
        3600.0,
        description="A removed element robots added is forgotten (memory and graph) once its removal's "
        "sense time is this old: a later report of its IRI with a class creates it anew, and a sighting "
        "sensed before the removal that arrives later than this is no longer refused as stale. 0: never "
        "forget (the graph keeps every removal, growing with every IRI robots mint).",
    )
    max_clock_skew_s: Annotated[Number, Field(ge=0.0, le=3600.0)] = Field(
        2.0,
        description="Until a robot's clock offset is known (clock_settle_s), a sense time later than the "
        "daemon's clock plus this is refused.",
    )
    max_clock_offset_s: Annotated[Number, Field(ge=0.0, le=3600.0)] = Field(
        0.5, description="The log warns once per robot whose clock offset estimate exceeds this."
    )
    clock_window_s: Annotated[Number, Field(gt=0.0, le=86400.0)] = Field(
        60.0, description="A robot's clock offset: the least arrival - sense time over this long."
    )
    clock_settle_s: Annotated[Number, Field(ge=0.0, le=86400.0)] = Field(
        5.0, description="Sense times are corrected by a robot's offset once its reports span this long."
    )
    classes: dict[str, FusionClassTable] = Field(
        default_factory=dict, description="Per IFC class (subtypes included): values that differ."
    )

    def rules(self) -> FusionRules:
        base = {k: getattr(self, k) for k in FusionClassTable.model_fields}
        return FusionRules(
            enabled=self.enabled,
            default=_class_rules(base),
            per_class={
                name: _class_rules(base | t.model_dump(exclude_none=True)) for name, t in self.classes.items()
            },
            refine_after=self.refine_after,
            refine_fraction=self.refine_fraction,
            refine_distance_m=self.refine_distance_m,
            move_sightings=self.move_sightings,
            certain_move_m=self.certain_move_m,
            disagreement_window_ns=int(self.disagreement_window_s * 1e9),
            resize_sightings=self.resize_sightings,
            resize_span_ns=int(self.resize_span_s * 1e9),
            merge_iou=self.merge_iou,
            tentative_sightings=self.tentative_sightings,
            stream_sightings=self.stream_sightings,
            stream_gap_ns=int(self.stream_gap_s * 1e9),
            alias_ttl_ns=int(self.alias_ttl_s * 1e9),
            alias_jump_m=self.alias_jump_m,
            tombstone_ttl_ns=int(self.tombstone_ttl_s * 1e9),
            max_skew_ns=int(self.max_clock_skew_s * 1e9),
            max_clock_offset_ns=int(self.max_clock_offset_s * 1e9),
            clock_window_ns=int(self.clock_window_s * 1e9),
            clock_settle_ns=int(self.clock_settle_s * 1e9),
        )


def _class_rules(v: Mapping[str, Any]) -> FusionClassRules:
    """The per-class values of a table (degrees and seconds as the core's radians and nanoseconds)."""
    return FusionClassRules(
        confirm_distance_m=v["confirm_distance_m"],
        confirm_angle_rad=math.radians(v["confirm_angle_deg"]),
        min_iou=v["min_iou"],
        small_object_m=v["small_object_m"],
        centre_distance_m=v["centre_distance_m"],
        misses_to_remove=int(v["misses_to_remove"]),
        miss_span_ns=int(v["miss_span_s"] * 1e9),
        ttl_ns=int(v["ttl_s"] * 1e9),
        size_ratio=v["size_ratio"],
        min_area_ratio=v["min_area_ratio"],
    )


@dataclass(frozen=True, slots=True)
class FusionClassRules:
    """The thresholds for one IFC class (and its subtypes), in metres, radians and nanoseconds."""

    confirm_distance_m: float
    confirm_angle_rad: float
    min_iou: float
    small_object_m: float
    centre_distance_m: float
    misses_to_remove: int
    miss_span_ns: int
    ttl_ns: int
    size_ratio: float = 0.35
    min_area_ratio: float = 0.5


@dataclass(frozen=True, slots=True)
class FusionRules:
    """``[fusion]`` as the core uses it."""

    enabled: bool = True
    default: FusionClassRules = FusionClassRules(0.15, math.radians(10.0), 0.25, 0.6, 0.3, 3, 10**9, 0)
    per_class: dict[str, FusionClassRules] | None = None
    refine_after: int = 10
    refine_fraction: float = 0.5
    refine_distance_m: float = 0.05
    move_sightings: int = 2
    certain_move_m: float = 0.5
    disagreement_window_ns: int = 10 * 10**9
    resize_sightings: int = 5
    resize_span_ns: int = 10**9
    merge_iou: float = 0.5
    tentative_sightings: int = 1
    stream_sightings: int = 2
    stream_gap_ns: int = 2 * 10**9
    alias_ttl_ns: int = 3600 * 10**9
    alias_jump_m: float = 2.0
    tombstone_ttl_ns: int = 3600 * 10**9
    max_skew_ns: int = 2 * 10**9
    max_clock_offset_ns: int = 5 * 10**8
    clock_window_ns: int = 60 * 10**9
    clock_settle_ns: int = 5 * 10**9

    def of(self, ifc_types: tuple[str, ...]) -> FusionClassRules:
        """The rules of the most specific configured class among ``ifc_types`` (class first)."""
        if self.per_class:
            for t in ifc_types:
                found = self.per_class.get(t)
                if found is not None:
                    return found
        return self.default
