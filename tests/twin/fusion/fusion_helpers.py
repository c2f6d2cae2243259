"""Helpers for fusion's tests: observations with descriptive types and sense times, map cells."""

from __future__ import annotations

import contextlib
import datetime
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

import twin.live.fuse as fuse_module
from tests.twin.box_lab import OX, OY
from tests.twin.live_helpers import PREFIX, box_turtle
from twin.live import TwinService

FURN = "http://pi.pauwel.be/voc/furniture#"


class Clock:
    """A service's clock that the test moves (``clock.ns += ...``)."""

    def __init__(self) -> None:
        self.ns = 1_800_000_000 * 10**9

    def __call__(self) -> int:
        return self.ns


@dataclass
class Settled:
    """How many arrays :func:`~twin.fusion.confirm_array.confirm_array` settled at once."""

    arrays: int = 0


@contextlib.contextmanager
def confirmations_at_once(enabled: bool) -> Iterator[Settled]:
    """Within: fusion's confirmations at once counted (``enabled``) or never taken (every report goes
    through the per-report rules), to compare both paths on the same script."""
    real = fuse_module.confirm_array
    settled = Settled()

    def counted(*args: object, **kw: object) -> bool:
        ok = enabled and real(*args, **kw)  # type: ignore[arg-type]
        settled.arrays += ok
        return ok

    fuse_module.confirm_array = counted  # type: ignore[assignment]
    try:
        yield settled
    finally:
        fuse_module.confirm_array = real


NAV = ("ground-floor", "lab-navigation")


def at(ns: int) -> str:
    seconds, nanos = divmod(ns, 1_000_000_000)
    moment = datetime.datetime.fromtimestamp(seconds, tz=datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f'"{moment}.{nanos:09d}Z"^^<http://www.w3.org/2001/XMLSchema#dateTime>'


def with_triples(payload: bytes, extra: str) -> bytes:
    """The one-element observation with ``extra`` predicate-object pairs appended (``a <...>``, ...)."""
    text = payload.decode().rstrip().removesuffix(".")
    return f"{text} ; {extra} .\n".encode()


def typed(payload: bytes, kind: str) -> bytes:
    """The observation with a descriptive type, e.g. ``typed(box, "Chair")`` for ``a furn:Chair``."""
    return with_triples(payload, f"a <{FURN}{kind}>")


def sensed(payload: bytes, ns: int) -> bytes:
    return with_triples(payload, f"twin:senseTime {at(ns)}")


CORRIDOR = [(4.2, 1.4), (7.8, 1.4), (7.8, 2.6), (4.2, 2.6)]
ROOM_A = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]


def view(
    ns: int, polygon: list[tuple[float, float]], *, detects: tuple[str, ...] = ("IfcFurnishingElement",)
) -> bytes:
    """A view (Turtle statements, no prefix) of the lab's ``polygon`` seen at ``ns``."""
    points = " ".join(f"{OX + x} {OY + y}" for x, y in polygon)
    classes = ", ".join(f'"{c}"' for c in detects)
    return (
        f'[] a twin:View ; twin:storey "ground-floor" ; twin:polygon "{points}" ; twin:detects {classes} ; '
        f"twin:senseTime {at(ns)} .\n"
    ).encode()


def view_only(ns: int, polygon: list[tuple[float, float]], **kw: tuple[str, ...]) -> bytes:
    return PREFIX.encode() + view(ns, polygon, **kw)


def box(iri: str, x: float, y: float, **kw: float | str) -> bytes:
    return box_turtle(iri, x, y, **kw)  # type: ignore[arg-type]


def cell(service: TwinService, x: float, y: float) -> int:
    """The navigation map's value at lab coordinates (x, y)."""
    m = service.live_maps.skill_maps[NAV]
    f = m.plan.frame
    col, row = int((OX + x - f.origin_x) / f.resolution_m), int((OY + y - f.origin_y) / f.resolution_m)
    return int(m.data[row, col])


def size_of(service: TwinService, iri: str) -> tuple[float, float, float]:
    """The element's world bounding-box sizes (x, y, z)."""
    b = service.live_maps.bounds_of(iri)
    assert b is not None
    return (round(b[3] - b[0], 3), round(b[4] - b[1], 3), round(b[5] - b[2], 3))


def assert_same_shapes(a: TwinService, b: TwinService) -> None:
    """Every element of ``a`` has the shape it has in ``b`` (mesh vertices and placement, or none)."""
    for iri in a.live.states:
        sa, sb = a.live.maps.shape_of(iri), b.live.maps.shape_of(iri)
        assert (sa is None) == (sb is None), iri
        if sa is not None and sb is not None:
            np.testing.assert_array_equal(sa[1], sb[1])
            np.testing.assert_array_equal(sa[0].vertices, sb[0].vertices)
