"""The core's tables: ``[site]``, ``[store]``, ``[import]``, ``[maps]``, ``[limits]`` and ``[rights]``
(``[robots.NAME]`` is in :mod:`twin.config.robots`, ``[skills.NAME]`` is parsed by
:func:`twin.selection.skills.parse_skill`). Each field's default is the value ``config/default.toml`` shows.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, model_validator

from twin.config.base import ConfigTable, Flag, Number, PathSetting, Text, Whole, check, list_of

Right = Literal["create", "dynamic", "doors", "static", "zones", "merges"]
RIGHTS: tuple[Right, ...] = ("create", "dynamic", "doors", "static", "zones", "merges")
Kernel = Literal["manifold", "opencascade", "cgal", "cgal-simple", "hybrid-cgal-simple-opencascade"]
KERNELS: tuple[Kernel, ...] = (
    "manifold", "opencascade", "cgal", "cgal-simple", "hybrid-cgal-simple-opencascade"
)  # fmt: skip
NAME_PATTERN = r"^[A-Za-z0-9_-]{1,64}$"
"""Site, robot and operator names: they become parts of key expressions and user names."""

STATIC_TYPES = (
    "IfcWall", "IfcSlab", "IfcColumn", "IfcBeam", "IfcCurtainWall", "IfcPlate", "IfcMember",
    "IfcStair", "IfcStairFlight", "IfcRamp", "IfcRampFlight", "IfcRoof", "IfcRailing", "IfcCovering",
    "IfcDoor", "IfcWindow", "IfcFooting", "IfcPile", "IfcChimney", "IfcOpeningElement",
)  # fmt: skip

SiteName = Annotated[Text, Field(pattern=NAME_PATTERN)]
DEFAULT_MAX_POINTS = 6_000_000
"""``[maps] max_points_per_storey`` unless set: about 1 GB while a storey's cloud is built."""
IfcClassName = Annotated[
    Text, check(lambda v: isinstance(v, str) and v.startswith("Ifc"), "an IFC class name")
]
Positive = Annotated[Number, Field(gt=0)]
PositiveWhole = Annotated[Whole, Field(gt=0)]


class SiteTable(ConfigTable):
    """``[site]``: the site's name and the base of its elements' IRIs."""

    name: SiteName = Field("lab", description="Site name: 1-64 of [A-Za-z0-9_-]; replaces {site}.")
    base_iri: Text = Field(
        "https://example.org/building-twin/{site}#",
        description='Elements are <base_iri><ifc type>_<uuid> (IFCtoLBD); "{site}" is the site name.',
    )


class StoreTable(ConfigTable):
    """``[store]``: the embedded graph store. A remote store's keys (``url``, ...) are added to this
    table by the SPARQL adapter (``adapters/sparql/settings.py``)."""

    extended_by_sections: ClassVar[bool] = True

    path: PathSetting = Field(Path("var/store"), description="The embedded pyoxigraph store (a directory).")
    flush_every_s: Annotated[Number, Field(ge=1.0, le=3600.0)] = Field(
        60.0, description="How often 'twin serve' flushes the embedded store's write buffers, seconds."
    )
    snapshot: Flag = Field(
        True,
        description="Keep 'twin serve's derived state (meshes, maps) in <path>.snapshot: restarts read it.",
    )
    snapshot_every_s: Annotated[Number, Field(ge=1.0, le=86400.0)] = Field(
        300.0, description="How often 'twin serve' rewrites the snapshot while anything changes, seconds."
    )


class ImportConfig(ConfigTable):
    """``[import]``: how an IFC model becomes the graph."""

    kernels: Annotated[tuple[Kernel, ...], list_of("geometry kernels"), Field(min_length=1)] = Field(
        ("manifold", "opencascade"),
        description="Geometry kernels, tried in order: each meshes only what the previous ones could not.",
    )
    threads: Annotated[Whole, Field(ge=1)] = 2
    static_types: Annotated[tuple[IfcClassName, ...], list_of("IFC class names")] = Field(
        STATIC_TYPES,
        description="IFC classes (and subtypes) of the fixed structure (twin:isStatic true).",
    )


class MapsTable(ConfigTable):
    """``[maps]``: the map frame's margin, where ``twin map`` writes files, and the points clouds' size
    limit."""

    margin_m: Annotated[Number, Field(ge=0.0, le=100.0)] = Field(
        1.0, description="Free space around a storey's extent, metres (the origin snaps to the resolution)."
    )
    out: PathSetting = Field(Path("var/maps"), description="Where 'twin map' writes its files.")
    max_points_per_storey: Annotated[Whole, Field(ge=1)] = Field(
        DEFAULT_MAX_POINTS,
        description=(
            "The most points a points skill's cloud of one storey may have, as estimated from the "
            "selected surfaces' area before building it (building takes about 160 bytes a point: "
            "the default fits in about 1 GB). Over it, 'twin map' refuses unless given --force and "
            "'twin serve' skips that cloud."
        ),
    )


class Limits(ConfigTable):
    """``[limits]``: bounds on what one message may ask of the daemon."""

    payload_bytes: PositiveWhole = Field(1 << 20, description="Largest observation (bytes of Turtle).")
    elements_per_observation: PositiveWhole = 256
    triangles_per_mesh: PositiveWhole = 200_000
    box_size_m: Positive = Field(50.0, description="Largest side of an observed box, metres.")
    site_margin_m: Positive = Field(
        20.0, description="Observed geometry lies within the site's extent grown by this, metres."
    )
    sparql_timeout_s: Positive = 5.0
    sparql_result_bytes: PositiveWhole = 16 << 20
    keyframe_interval_s: Annotated[Number, Field(ge=1.0, le=86400.0)] = Field(
        60.0,
        description="A map that changed since its last full publication is published in full again "
        "(a keyframe: heals a lost update, refreshes caches) at most this often, seconds; between "
        "keyframes a change goes out as its updates only.",
    )

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data: Any) -> Any:
        if isinstance(data, dict) and "full_map_interval_s" in data:
            msg = (
                f"full_map_interval_s = {data['full_map_interval_s']!r} is gone: a change now goes out "
                "as its updates only, and a changed map in full at most every keyframe_interval_s "
                "(default 60); remove the key, or set keyframe_interval_s"
            )
            raise ValueError(msg)
        return data


class RightsTable(ConfigTable):
    """``[rights]``: what a robot may do unless its ``[robots.NAME]`` table says otherwise."""

    default: Annotated[tuple[Right, ...], list_of("rights")] = ("create", "dynamic", "doors")
