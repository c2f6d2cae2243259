"""Namespaces, terms and IRI minting of the graph world model (Linked Building Data).

Element IRIs follow IFCtoLBD: ``<base><ifc type lowercased without "ifc">_<uncompressed GlobalId>``,
e.g. ``https://example.org/lab#wallstandardcase_0e5d1b7c-...``, so the graph joins with other LBD
tools. The project's own terms live in one namespace, ``TWIN``.

Example::

    from twin.graph import vocab
    iri = vocab.entity_iri("https://example.org/lab#", "IfcWall", "2O2Fr$t4X7Zf8NOew3FLOH")
"""

from __future__ import annotations

import binascii
import re
from typing import Final

from twin.errors import ModelError

BOT: Final = "https://w3id.org/bot#"
BEO: Final = "https://pi.pauwel.be/voc/buildingelement#"
FURN: Final = "http://pi.pauwel.be/voc/furniture#"
PROPS: Final = "https://w3id.org/props#"
OMG: Final = "https://w3id.org/omg#"
FOG: Final = "https://w3id.org/fog#"
TWIN: Final = "https://w3id.org/building-twin#"
RDF: Final = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
RDFS: Final = "http://www.w3.org/2000/01/rdf-schema#"
XSD: Final = "http://www.w3.org/2001/XMLSchema#"

PREFIXES: Final[dict[str, str]] = {
    "bot": BOT,
    "beo": BEO,
    "furn": FURN,
    "props": PROPS,
    "omg": OMG,
    "fog": FOG,
    "twin": TWIN,
    "rdf": RDF,
    "rdfs": RDFS,
    "xsd": XSD,
}


def sparql_prefixes() -> str:
    """The ``PREFIX`` lines for every namespace above, to put before a query."""
    return "".join(f"PREFIX {p}: <{iri}>\n" for p, iri in PREFIXES.items())


# --- terms ------------------------------------------------------------------------------------
RDF_TYPE: Final = RDF + "type"
RDFS_LABEL: Final = RDFS + "label"

BOT_SITE: Final = BOT + "Site"
BOT_BUILDING: Final = BOT + "Building"
BOT_STOREY: Final = BOT + "Storey"
BOT_SPACE: Final = BOT + "Space"
BOT_ELEMENT: Final = BOT + "Element"
BOT_HAS_BUILDING: Final = BOT + "hasBuilding"
BOT_HAS_STOREY: Final = BOT + "hasStorey"
BOT_HAS_SPACE: Final = BOT + "hasSpace"
BOT_ADJACENT_ELEMENT: Final = BOT + "adjacentElement"
BOT_CONTAINS_ELEMENT: Final = BOT + "containsElement"
BOT_HAS_SUB_ELEMENT: Final = BOT + "hasSubElement"

PROPS_GLOBAL_ID: Final = PROPS + "globalIdIfcRoot_attribute_simple"
PROPS_NAME: Final = PROPS + "nameIfcRoot_attribute_simple"

OMG_HAS_GEOMETRY: Final = OMG + "hasGeometry"
OMG_GEOMETRY: Final = OMG + "Geometry"
FOG_PLY_BINARY_LE: Final = FOG + "asPly_v1.0-binaryLE"
XSD_BASE64: Final = XSD + "base64Binary"
XSD_DOUBLE: Final = XSD + "double"
XSD_BOOLEAN: Final = XSD + "boolean"
XSD_INTEGER: Final = XSD + "integer"
XSD_DECIMAL: Final = XSD + "decimal"

TWIN_IFC_CLASS: Final = TWIN + "ifcClass"
TWIN_IFC_TYPE: Final = TWIN + "ifcType"
TWIN_MATERIAL: Final = TWIN + "material"
TWIN_FACING_MATERIAL: Final = TWIN + "facingMaterial"
"""The materials a sensor faces (a subset of ``twin:material``): what "made of glass" is judged on."""
TWIN_MESH_KERNEL: Final = TWIN + "meshKernel"
"""The geometry kernel that meshed an element's body (e.g. "manifold", "opencascade")."""
TWIN_IS_STATIC: Final = TWIN + "isStatic"
TWIN_PREDEFINED_TYPE: Final = TWIN + "predefinedType"
"""The IFC ``PredefinedType`` of a door, lift or slab (e.g. "ELEVATOR", "ROOF"), as a string."""
TWIN_OPERATION_TYPE: Final = TWIN + "operationType"
"""A door's IFC ``OperationType`` (e.g. "SINGLE_SWING_LEFT", "SLIDING_TO_RIGHT"), as a string."""
TWIN_ELEVATION: Final = TWIN + "elevation"
TWIN_STOREY_KEY: Final = TWIN + "storeyKey"
TWIN_PLACEMENT: Final = TWIN + "placement"
TWIN_MATRIX4: Final = TWIN + "Matrix4x4"
TWIN_CLOSED: Final = TWIN + "closedMesh"
TWIN_SOLID: Final = TWIN + "solid"
"""On a geometry node, ``true`` when the source model says the body is a solid (not a surface): its
section is filled where it is made of closed loops even if the mesh is not watertight. Absent: unknown
(treated as a surface, as before the term existed)."""
TWIN_TRIANGLES: Final = TWIN + "triangleCount"
TWIN_MODEL: Final = TWIN + "Model"
TWIN_SOURCE: Final = TWIN + "sourceFile"
TWIN_SCHEMA: Final = TWIN + "ifcSchema"
TWIN_SOURCE_LINES: Final = TWIN + "sourceLines"
TWIN_MESH_FAILED: Final = TWIN + "meshFailed"
TWIN_KERNEL_FALLBACK: Final = TWIN + "kernelFallback"
TWIN_REVISION: Final = TWIN + "revision"
TWIN_EXTENT: Final = TWIN + "extent"
"""A storey's map extent: ``"xmin ymin xmax ymax"`` in metres (fixed at import: maps never move)."""
# Observations (robot-reported changes) and their provenance.
TWIN_STOREY: Final = TWIN + "storey"
TWIN_BOX: Final = TWIN + "box"
TWIN_IS_OPEN: Final = TWIN + "isOpen"
TWIN_REMOVED: Final = TWIN + "removed"
# Zones nav2's costmap filters read (operators mark them; keepout and speed skills map them).
TWIN_KEEPOUT: Final = TWIN + "keepout"
"""``true``: robots must not enter the element's footprint (a ``keepout`` skill's mask)."""
TWIN_SPEED_LIMIT: Final = TWIN + "speedLimit"
"""Integer percent of the robot's maximum speed inside the element's footprint (a ``speed`` skill's
mask); 0 lifts the limit."""
TWIN_OBSERVED_BY: Final = TWIN + "observedBy"
TWIN_OBSERVED_AT: Final = TWIN + "observedAt"
# Many robots, one twin (fusion): views, sense times, aliases, merges and removals by absence.
TWIN_SENSE_TIME: Final = TWIN + "senseTime"
"""When the change was seen (``xsd:dateTime``): on an element (its last applied change), or on a view."""
TWIN_VIEW: Final = TWIN + "View"
"""What a robot looked at: ``twin:storey``, ``twin:polygon`` (the floor it saw), ``twin:detects``;
optionally ``twin:hole`` and ``twin:origin``."""
TWIN_POLYGON: Final = TWIN + "polygon"
TWIN_HOLE: Final = TWIN + "hole"
"""On a view: floor inside its polygons that the sensor did not see (a shadow), ``x y`` pairs."""
TWIN_ORIGIN: Final = TWIN + "origin"
"""On a view: the sensor's position, ``"x y z"`` (map frame; z above the storey's elevation)."""
TWIN_DETECTS: Final = TWIN + "detects"
TWIN_DISTINCT: Final = TWIN + "distinct"
"""``true`` on a robot IRI: a new object, never associated with an element the twin holds."""
TWIN_UNMERGE: Final = TWIN + "unmerge"
TWIN_LIFETIME: Final = TWIN + "lifetime"
"""How long a report holds from its observation, seconds (Open-RMF obstacles' lifetime): kept so that
the reporter finds it again after a restart."""
"""``true`` on an alias: undo the merge; the IRI becomes an element of its own again."""
TWIN_ALIAS_OF: Final = TWIN + "aliasOf"
"""A robot IRI that resolved to an element the twin holds (kept until unused for ``alias_ttl_s``)."""
TWIN_MERGED_INTO: Final = TWIN + "mergedInto"
TWIN_REMOVED_BECAUSE: Final = TWIN + "removedBecause"
XSD_DATETIME: Final = XSD + "dateTime"
XSD_STRING: Final = XSD + "string"
# Skill profiles added at run time (kept in the graph so that they survive a restart).
TWIN_SKILL: Final = TWIN + "Skill"
TWIN_PROFILE_JSON: Final = TWIN + "profileJson"

# IFC classes whose BEO / FURN class is not simply the IFC name without "Ifc" and suffixes.
_BEO_CLASSES: Final = frozenset(
    {
        "Beam",
        "BuildingElementProxy",
        "Chimney",
        "Column",
        "Covering",
        "CurtainWall",
        "Door",
        "Footing",
        "Member",
        "Pile",
        "Plate",
        "Railing",
        "Ramp",
        "RampFlight",
        "Roof",
        "ShadingDevice",
        "Slab",
        "Stair",
        "StairFlight",
        "Wall",
        "Window",
        "BuildingElementPart",
        "DiscreteAccessory",
        "ElementAssembly",
        "Fastener",
        "MechanicalFastener",
        "ReinforcingBar",
        "ReinforcingMesh",
        "Tendon",
        "TendonAnchor",
        "TransportElement",
        "VirtualElement",
        "OpeningElement",
        "GeographicElement",
        "CivilElement",
    }
)
_FURN_CLASSES: Final = {
    "FurnishingElement": "Furniture",
    "Furniture": "Furniture",
    "SystemFurnitureElement": "SystemFurnitureElement",
}
_SUFFIXES: Final = ("StandardCase", "ElementedCase")
_RENAMED: Final = {"Opening": "OpeningElement"}  # IfcOpeningStandardCase


def semantic_class(ifc_class: str) -> str | None:
    """The BEO or FURN class IRI for an IFC class, or None when LBD has none (e.g. flow terminals).

    >>> semantic_class("IfcWallStandardCase")
    'https://pi.pauwel.be/voc/buildingelement#Wall'
    """
    name = ifc_class.removeprefix("Ifc")
    for suffix in _SUFFIXES:
        name = name.removesuffix(suffix)
    name = _RENAMED.get(name, name)
    if name in _FURN_CLASSES:
        return FURN + _FURN_CLASSES[name]
    if name in _BEO_CLASSES:
        return BEO + name
    return None


# --- GlobalId -----------------------------------------------------------------------------------
_GUID_CHARS: Final = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$"
_GUID_INDEX: Final = {c: i for i, c in enumerate(_GUID_CHARS)}
_TO_BASE64: Final = bytes.maketrans(
    _GUID_CHARS.encode(), b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/"
)  # the same 6-bit digits in the standard base-64 alphabet
_GUID: Final = re.compile(r"[0-3][0-9A-Za-z_$]{21}")  # _GUID_CHARS after a first character of 0-3


def expand_guid(guid: str) -> str:
    """Uncompress a 22-character IFC GlobalId to a lower-case UUID ``8-4-4-4-12``.

    >>> expand_guid("0" * 22)
    '00000000-0000-0000-0000-000000000000'
    """
    if type(guid) is str and _GUID.fullmatch(guid) is not None:
        # "AA" + 22 digits = 24 digits = 18 bytes: 16 zero bits, then the 128 bits of the GlobalId
        h = binascii.a2b_base64(b"AA" + guid.encode().translate(_TO_BASE64))[2:].hex()
        return f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:]}"
    if len(guid) != 22 or guid[0] not in "0123" or any(c not in _GUID_INDEX for c in guid):
        msg = f"Not an IFC GlobalId (22 characters of the IFC base-64 alphabet): {guid!r}."
        raise ModelError(msg)
    value = 0
    for c in guid:
        value = value * 64 + _GUID_INDEX[c]
    h = f"{value:032x}"
    return f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:]}"


def compress_guid(uuid: str) -> str:
    """Inverse of :func:`expand_guid`: a UUID (with or without dashes) to a 22-character GlobalId."""
    h = uuid.replace("-", "")
    if len(h) != 32:
        msg = f"Not a UUID: {uuid!r}."
        raise ModelError(msg)
    value = int(h, 16)
    chars = []
    for _ in range(22):
        value, r = divmod(value, 64)
        chars.append(_GUID_CHARS[r])
    return "".join(reversed(chars))


# --- IRIs ---------------------------------------------------------------------------------------
def check_base(base_iri: str) -> str:
    """Return ``base_iri`` if usable as an IRI prefix (absolute, ending in ``#`` or ``/``)."""
    if "://" not in base_iri or base_iri[-1] not in "#/" or any(c in base_iri for c in ' <>"{}|\\^`'):
        msg = f"Base IRI must be absolute and end with '#' or '/', got {base_iri!r}."
        raise ModelError(msg)
    return base_iri


def entity_iri(base_iri: str, ifc_class: str, guid: str) -> str:
    """The IFCtoLBD IRI of any rooted IFC entity (element, space, storey, building, site)."""
    kind = ifc_class.lower().removeprefix("ifc")
    return f"{base_iri}{kind}_{expand_guid(guid)}"


def geometry_iri(entity: str) -> str:
    """The IRI of an element's geometry node: the element IRI with ``/geometry`` appended."""
    return f"{entity}/geometry"


def skill_iri(base_iri: str, name: str) -> str:
    """The IRI of a skill profile added at run time."""
    return f"{base_iri}skill_{name}"


def model_iri(base_iri: str) -> str:
    """The IRI of the node describing the import itself (source file, schema, counts)."""
    return f"{base_iri}model"


def storey_key(name: str, used: set[str] | None = None) -> str:
    """A stable, URL- and key-expression-safe key for a storey name.

    ``"1. Obergeschoss"`` gives ``"1-obergeschoss"``.

    When ``used`` is given, a numeric suffix makes the key unique and the key is added to it.
    """
    out = []
    for c in name.lower():
        out.append(c if c.isascii() and c.isalnum() else "-")
    key = "-".join(filter(None, "".join(out).split("-"))) or "storey"
    if used is None:
        return key
    candidate, n = key, 2
    while candidate in used:
        candidate = f"{key}-{n}"
        n += 1
    used.add(candidate)
    return candidate


SITE_SLUG_MAX: Final = 64
"""A site name is at most this long (``site.name`` of the configuration)."""


def site_slug(file_name: str) -> str:
    """The default site name of a model file: its stem, lower-case, runs of anything but ``[a-z0-9]``
    as one ``-``, at most 64 characters; ``"site"`` if nothing is left.

    ``"revit2012_janesville_restaurant.ifc"`` gives ``"revit2012-janesville-restaurant"``.
    """
    stem = file_name.rsplit("/", 1)[-1]
    if "." in stem.lstrip("."):
        stem = stem[: stem.rindex(".")]
    out = "".join(c if c.isascii() and c.isalnum() else "-" for c in stem.lower())
    slug = "-".join(filter(None, out.split("-")))[:SITE_SLUG_MAX].strip("-")
    return slug or "site"
