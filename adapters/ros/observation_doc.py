"""Observation documents (Turtle, the wire format of ``docs/observations.md``) written from what a
ROS 2 message said: boxes, door states, removals and the view a sensor had (the fusion terms
``twin:View``, ``twin:polygon``, ``twin:hole``, ``twin:origin``, ``twin:detects``, ``twin:senseTime``).

Pure functions and immutable records. Numbers are written in metres to 0.1 mm and radians to 1 µrad,
so a message that is sent again gives the same bytes (the core acks a re-confirmation at once).

Example::

    doc = observation_turtle(
        boxes=[BoxReport("urn:r:7", "IfcFurniture", "ground-floor", (2, 3, 0.4, 1.2, 0.8, 0.75, 0))],
        view=ViewReport("ground-floor", (((0, 0), (4, -2), (4, 2)),), ("IfcFurniture",), origin=(0, 0, 1.2)),
        sense_ns=1_700_000_000_000_000_000,
    )
"""

from __future__ import annotations

import datetime as dt
import functools
import math
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from urllib.parse import quote

import numpy as np
import numpy.typing as npt

from twin.live.validate import Checked
from twin.records import ElementReport, Observation, ObservedView, boxed_report

__all__ = [
    "BoxReport",
    "RosInputError",
    "Translation",
    "ViewReport",
    "literal",
    "observation_records",
    "observation_turtle",
    "robot_iri",
    "sense_time",
]

PREFIXES = (
    "@prefix twin: <https://w3id.org/building-twin#> .\n"
    "@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n"
    "@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .\n"
)


class RosInputError(Exception):
    """A message (or one detection of it) that cannot become an observation; ``cause`` counts it
    (``malformed``, ``wrong_type``, ``unknown_frame``, ``extrapolation``, ``disconnected``, ``future``,
    ``oversized``, ``pose``, ``size``, ``tilt``, ``no_storey``, ``unknown_level``, ``unknown_door``)."""

    def __init__(self, cause: str, message: str) -> None:
        super().__init__(message)
        self.cause = cause


@dataclass(frozen=True, slots=True)
class BoxReport:
    """An element seen as an oriented box: ``(cx, cy, cz, sx, sy, sz, yaw)``, centre in the map frame
    (cz above the storey's elevation), sizes in metres, yaw in radians."""

    iri: str
    ifc_class: str
    storey: str
    box: tuple[float, float, float, float, float, float, float]
    label: str | None = None
    lifetime_s: float | None = None
    """How long the report holds (``twin:lifetime``; an Open-RMF obstacle's lifetime, 0: for ever)."""
    kind: str | None = None
    """A descriptive type IRI (``furn:Chair`` expanded), written as ``a <kind>``."""


Ring = tuple[tuple[float, float], ...] | npt.NDArray[np.float64]
"""A closed ring of points: ``(x, y)`` pairs, or an ``(n, 2) float64`` array of them."""


@dataclass(frozen=True, slots=True)
class ViewReport:
    """What a sensor looked at: the floor it saw on ``storey`` (the union of simple ``polygons`` less
    ``holes``, map frame, metres), the IFC classes its detector reports and the sensor's ``origin``
    (x, y, z above the storey's floor)."""

    storey: str
    polygons: tuple[Ring, ...]
    detects: tuple[str, ...]
    holes: tuple[Ring, ...] = ()
    origin: tuple[float, float, float] | None = None


@dataclass(frozen=True, slots=True)
class Translation:
    """A message turned into an observation: ``document`` (None: nothing to tell the twin), the robot
    IRIs it describes, and what was left out (``ignored``: by cause; ``refused``: (cause, message))."""

    document: bytes | Observation | Checked | None
    """Turtle (the wire format), or the typed records the same Turtle parses to (in the daemon's process;
    :class:`~twin.live.validate.Checked` once an ingest worker checked them)."""
    iris: tuple[str, ...] = ()
    ignored: dict[str, int] = field(default_factory=dict)
    refused: tuple[tuple[str, str], ...] = ()
    extra: tuple[bytes | Observation, ...] = ()
    """More documents to submit after ``document``, each on its own (e.g. one removal each, so that a
    removal the twin refuses takes no other change with it)."""
    settle: Callable[[bool], None] | None = field(default=None, compare=False)
    """Told whether the twin accepted ``document`` (e.g. an obstacle tracker forgets what was refused)."""
    removes: tuple[str, ...] = ()
    """The element each of ``extra`` removes, if they are removals (an obstacle tracker retries one the
    twin refused while it still holds the element)."""

    @property
    def documents(self) -> tuple[bytes | Observation | Checked, ...]:
        return ((self.document,) if self.document is not None else ()) + self.extra

    def __reduce__(self) -> tuple[type[Translation], tuple[object, ...]]:
        """A call with its fields (an ingest worker hands one over per array): the setstate of a frozen
        dataclass with slots looks its fields up again at every load."""
        return (Translation, _TRANSLATION_FIELDS(self))


_TRANSLATION_FIELDS = operator.attrgetter(*Translation.__slots__)


@functools.lru_cache(maxsize=8192)  # a robot's tracks are named again at every array
def robot_iri(owner: str, kind: str, local: str) -> str:
    """A stable IRI an owner (robot or source) mints, e.g. ``urn:twin-ros:robot1:det:obj%2F7``."""
    return f"urn:twin-ros:{quote(owner, safe='')}:{kind}:{quote(local, safe='')}"


def literal(text: str) -> str:
    """A Turtle string literal."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n").replace("\r", "\\r")
    return f'"{escaped}"'


def sense_time(stamp_ns: int) -> str:
    """``"2026-11-27T10:00:01.250000Z"^^xsd:dateTime`` of integer nanoseconds since the epoch (UTC)."""
    seconds, ns = divmod(stamp_ns, 1_000_000_000)
    when = dt.datetime.fromtimestamp(seconds, tz=dt.UTC).replace(microsecond=ns // 1000)
    return f'"{when.strftime("%Y-%m-%dT%H:%M:%S.%f")}Z"^^xsd:dateTime'


def _metres(v: float) -> str:
    text = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _points(ring: Ring) -> str:
    points = ring.tolist() if isinstance(ring, np.ndarray) else ring
    return " ".join(f"{_metres(x)} {_metres(y)}" for x, y in points)


def _radians(v: float) -> str:
    v = math.remainder(v, 2 * math.pi)
    text = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def observation_turtle(
    *,
    boxes: Sequence[BoxReport] = (),
    doors: Sequence[tuple[str, bool]] = (),
    removed: Sequence[str] = (),
    view: ViewReport | None = None,
    sense_ns: int | None = None,
    fusion_terms: bool = True,
) -> bytes | None:
    """The Turtle of one observation, or None when it says nothing.

    ``fusion_terms`` False leaves out the view and the sense time (for a core that does not read them
    yet): the elements alone.
    """
    lines: list[str] = []
    for b in boxes:
        cx, cy, cz, sx, sy, sz, yaw = b.box
        numbers = " ".join([*(_metres(v) for v in (cx, cy, cz, sx, sy, sz)), _radians(yaw)])
        label = f" ;\n    rdfs:label {literal(b.label)}" if b.label else ""
        if b.lifetime_s is not None:
            label += f' ;\n    twin:lifetime "{b.lifetime_s:.9f}"^^xsd:decimal'
        if b.kind:
            label += f" ;\n    a <{b.kind}>"
        lines.append(
            f"<{b.iri}> twin:ifcClass {literal(b.ifc_class)} ; twin:storey {literal(b.storey)} ;\n"
            f'    twin:box "{numbers}"{label} .'
        )
    lines += [f"<{iri}> twin:isOpen {'true' if is_open else 'false'} ." for iri, is_open in doors]
    lines += [f"<{iri}> twin:removed true ." for iri in removed]
    rings = [p for p in view.polygons if len(p) >= 3] if view is not None else []
    if fusion_terms and view is not None and rings:
        parts = [f"[] a twin:View ;\n    twin:storey {literal(view.storey)}"]
        if sense_ns is not None:
            parts.append(f"twin:senseTime {sense_time(sense_ns)}")
        if view.origin is not None:
            parts.append(f'twin:origin "{" ".join(_metres(v) for v in view.origin)}"')
        parts += [f'twin:polygon "{_points(p)}"' for p in rings]
        parts += [f'twin:hole "{_points(h)}"' for h in view.holes if len(h) >= 3]
        if view.detects:
            parts.append("twin:detects " + " , ".join(literal(c) for c in view.detects))
        lines.append(" ;\n    ".join(parts) + " .")
    elif fusion_terms and sense_ns is not None and (boxes or doors):
        stamp = sense_time(sense_ns)
        lines += [
            f"<{iri}> twin:senseTime {stamp} ." for iri in [b.iri for b in boxes] + [d for d, _ in doors]
        ]
    if not lines:
        return None
    return (PREFIXES + "\n".join(lines) + "\n").encode()


def _m(v: float) -> float:
    """``v`` as :func:`_metres` writes it and the parser reads it back (0.1 mm; no negative zero)."""
    return round(v, 4) + 0.0


def _rad(v: float) -> float:
    return round(math.remainder(v, 2 * math.pi), 6) + 0.0


def _rounded(values: np.ndarray, digits: int | np.ndarray) -> np.ndarray:
    """``values`` (any shape) as ``round(v, digits) + 0.0`` rounds each, at once (``digits``: one for
    all, or one per column): ``rint(v * 10**digits) / 10**digits`` is that wherever ``v * 10**digits``
    is not within 1e-6 of a half (its error is below 1e-7 for any value under 1e9 / 10**digits);
    those few are rounded one by one. NaN and inf stay."""
    v = np.asarray(values, dtype=np.float64)
    scale = 10.0 ** np.asarray(digits, dtype=np.float64)
    scaled = v * scale
    k = np.rint(scaled)
    out = k / scale + 0.0
    with np.errstate(invalid="ignore"):
        tie = np.abs(np.abs(scaled - k) - 0.5) < 1e-6
    if tie.any():
        each = np.broadcast_to(np.asarray(digits), v.shape)[tie].tolist()
        out[tie] = [round(float(x), int(n)) + 0.0 for x, n in zip(v[tie], each, strict=True)]
    return out


_BOX_DIGITS = np.array([4, 4, 4, 4, 4, 4, 6])
"""A box's numbers as written: metres to 0.1 mm, its yaw to 1 µrad."""


def _ring(ring: Ring | Sequence[tuple[float, float]]) -> np.ndarray:
    """The ring's points as :func:`_m` rounds each, at once (:func:`_rounded`)."""
    return _rounded(np.asarray(ring, dtype=np.float64).reshape(-1, 2), 4)


def observation_records(
    *,
    boxes: Sequence[BoxReport] = (),
    doors: Sequence[tuple[str, bool]] = (),
    removed: Sequence[str] = (),
    view: ViewReport | None = None,
    sense_ns: int | None = None,
    fusion_terms: bool = True,
) -> Observation | None:
    """The typed records that :func:`observation_turtle`'s document parses to (the same numbers, rounded
    as written; the same order), for an adapter in the daemon's process: no Turtle written or parsed.
    The core checks them as it checks a parsed document (:func:`twin.live.validate.check_observation`)."""
    rings = [p for p in view.polygons if len(p) >= 3] if view is not None else []
    with_view = fusion_terms and view is not None and bool(rings)
    stamp = sense_ns - sense_ns % 1000 if sense_ns is not None else None  # written to the microsecond
    each_sense = stamp if fusion_terms and not with_view else None
    reports: dict[str, ElementReport] = {}
    # every box's numbers rounded as _m and _rad round each (at once: 20 boxes are 140 numbers)
    numbers = np.array([b.box for b in boxes], dtype=np.float64).reshape(-1, 7)
    numbers[:, 6] = [math.remainder(v, 2 * math.pi) for v in numbers[:, 6].tolist()]
    for b, (cx, cy, cz, sx, sy, sz, yaw) in zip(boxes, _rounded(numbers, _BOX_DIGITS).tolist(), strict=True):
        reports[b.iri] = boxed_report(
            b.iri,
            b.ifc_class,
            b.storey,
            (cx, cy, cz, sx, sy, sz, yaw),
            labels=(b.label,) if b.label else (),
            classes=(b.kind,) if b.kind else (),
            sense_ns=each_sense,
            lifetime_s=None if b.lifetime_s is None else round(b.lifetime_s, 9),
        )
    for iri, is_open in doors:
        reports[iri] = ElementReport(iri, is_open=is_open, sense_ns=each_sense)
    for iri in removed:
        reports[iri] = ElementReport(iri, removed=True)
    observed = None
    if with_view and view is not None:
        observed = ObservedView(
            view.storey,
            tuple(_ring(p) for p in rings),
            tuple(dict.fromkeys(view.detects)),
            stamp,
            holes=tuple(_ring(h) for h in view.holes if len(h) >= 3),
            origin=None
            if view.origin is None
            else (_m(view.origin[0]), _m(view.origin[1]), _m(view.origin[2])),
        )
    if not reports and observed is None:
        return None
    ordered = tuple(reports[i] for i in sorted(reports, key=lambda i: f"<{i}>"))
    return Observation(ordered, observed)
