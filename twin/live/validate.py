"""The checks every observation passes, whichever way it came: parsed from Turtle (a Zenoh
observation, :mod:`twin.live.parse`) or handed over as typed records (the ROS 2 ingest in the
daemon's process). One validator for both paths: what it refuses, it refuses with the same message.

What needs the syntax (a literal's datatype, one value per term, unknown terms) is the parser's; what
needs the graph (does the element exist, may this robot change it) is :mod:`twin.live`'s. Here: the
values themselves, against :class:`~twin.config.Limits`.

Where typed records are made in another process (the ROS 2 ingest workers), they are checked there
(:func:`checked`): a :class:`Checked` observation carries the limits it passed, and the writer takes it
without checking it again when its own limits are the same (:meth:`Checked.passed`). One that fails
goes on unmarked, and the writer refuses it with the same message, counted as any refusal.

Example::

    check_observation(Observation((ElementReport("urn:r:1", "IfcFurniture", "s", box),)), limits=Limits())
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import numpy as np

from twin.config import Limits
from twin.errors import ObservationError
from twin.graph import vocab
from twin.records import ElementReport, Observation, ObservedView

__all__ = [
    "MAX_LIFETIME_S",
    "MAX_VIEW_POINTS",
    "Checked",
    "check_iri",
    "check_observation",
    "check_report",
    "check_view",
    "checked",
    "limits_key",
]

MAX_VIEW_POINTS = 4096
"""Vertices of all the polygons of one view together."""
MAX_LIFETIME_S = 7 * 86400.0
"""The longest ``twin:lifetime`` taken (a week): beyond it a report is not transient."""
MAX_TEXT = 1024
"""Characters of a label or material at most."""
_IRI = re.compile(r'^[A-Za-z][A-Za-z0-9+.-]*:[^<>"{}|^`\\\s]*$')
_IFC_CLASS = re.compile(r"Ifc[A-Za-z0-9]{1,64}")


def _fail(message: str) -> ObservationError:
    return ObservationError(message)


def check_iri(subject: str) -> None:
    """ObservationError unless ``subject`` is an absolute IRI of at most 2048 characters."""
    if len(subject) > 2048 or not _is_iri(subject):
        raise _fail(f"Element IRI {subject[:200]!r} is not an absolute IRI.")


@functools.lru_cache(maxsize=2048)
def _is_iri(subject: str) -> bool:
    """Whether ``subject`` (at most 2048 characters) is an absolute IRI: remembered, the same IRIs come
    again and again (a robot's objects, array after array)."""
    return _IRI.match(subject) is not None


def _is_ifc_class(name: str) -> bool:
    """Whether ``name`` is an IFC class name (``Ifc`` and at most 64 letters or digits)."""
    return len(name) <= 67 and _ifc_class_name(name)


@functools.lru_cache(maxsize=256)
def _ifc_class_name(name: str) -> bool:
    return _IFC_CLASS.fullmatch(name) is not None


def check_report(report: ElementReport, *, limits: Limits) -> ElementReport:
    """``report`` if its values are acceptable; ObservationError naming the first that is not."""
    subject = report.iri
    check_iri(subject)
    if report.ifc_class is not None and not _is_ifc_class(report.ifc_class):
        raise _fail(f"Element <{subject}>: twin:ifcClass {report.ifc_class!r} is not an IFC class name.")
    if report.box is not None:
        b = report.box
        isfinite, most = math.isfinite, limits.box_size_m
        if not (
            isfinite(b.cx) and isfinite(b.cy) and isfinite(b.cz) and isfinite(b.sx) and isfinite(b.sy)
            and isfinite(b.sz) and isfinite(b.yaw)
        ):  # fmt: skip
            values = (b.cx, b.cy, b.cz, b.sx, b.sy, b.sz, b.yaw)
            raise _fail(f"Element <{subject}>: twin:box has a NaN or infinite number: {values}.")
        if not (0.0 < b.sx <= most and 0.0 < b.sy <= most and 0.0 < b.sz <= most):
            sizes = (("sx", b.sx), ("sy", b.sy), ("sz", b.sz))
            name, size = next((n, v) for n, v in sizes if not 0.0 < v <= most)
            raise _fail(f"Element <{subject}>: box size {name}={size} m is outside (0, {most}] m.")
        if report.storey is None:
            raise _fail(f"Element <{subject}>: twin:box needs twin:storey (its z is above that storey).")
    if (report.box is not None) + (report.geometry is not None) + (report.placement is not None) > 1:
        given = (("box", report.box), ("geometry", report.geometry), ("placement", report.placement))
        geometries = [k for k, v in given if v is not None]
        raise _fail(
            f"Element <{subject}>: give one of twin:box, omg:hasGeometry or twin:placement, not {geometries}."
        )
    if report.speed_limit is not None and not 0 <= report.speed_limit <= 100:
        raise _fail(
            f"Element <{subject}>: twin:speedLimit must be a percent from 0 (no limit) to 100, "
            f"got {str(report.speed_limit)!r}."
        )
    if report.lifetime_s is not None and not 0.0 <= report.lifetime_s <= MAX_LIFETIME_S:
        raise _fail(
            f"Element <{subject}>: twin:lifetime must be seconds from 0 to {MAX_LIFETIME_S:g}, "
            f"got {report.lifetime_s!r}."
        )
    for cls in report.classes:
        if not (cls.startswith((vocab.BEO, vocab.FURN)) or cls == vocab.BOT_ELEMENT):
            raise _fail(
                f"Element <{subject}>: rdf:type <{cls}> is not allowed; only BEO and FURN classes "
                "(e.g. furn:Table) and bot:Element."
            )
    for what, texts in (("rdfs:label", report.labels), ("twin:material", report.materials)):
        if texts and any(len(t) > MAX_TEXT for t in texts):
            raise _fail(f"Element <{subject}>: {what} is longer than {MAX_TEXT} characters.")
    marks = report.keepout is not None or report.speed_limit is not None
    if report.removed and (
        report.changes_geometry or report.is_open is not None or report.ifc_class or marks
    ):
        raise _fail(f"Element <{subject}>: twin:removed true cannot come with other changes.")
    return report


def check_view(view: ObservedView, *, name: str = "[]") -> ObservedView:
    """``view`` if it is usable; ObservationError naming the first problem."""
    where = f"The view {name}"
    points = 0
    for term, rings in (("twin:polygon", view.polygons), ("twin:hole", view.holes)):
        for ring in rings:
            if np.ndim(ring) != 2 or np.shape(ring)[1] != 2 or len(ring) < 3:
                raise _fail(
                    f"{where}: {term} must be x y pairs of at least 3 points, got shape {np.shape(ring)}."
                )
            if not np.isfinite(ring).all():
                raise _fail(f"{where}: {term} has a NaN or infinite number.")
            points += len(ring)
            if points > MAX_VIEW_POINTS:
                raise _fail(f"{where}: its polygons have more than {MAX_VIEW_POINTS} points.")
    if view.origin is not None and not all(math.isfinite(v) for v in view.origin):
        raise _fail(f"{where}: twin:origin has a NaN or infinite number: {view.origin}.")
    if not view.polygons:
        raise _fail(f"{where} has no twin:polygon (the floor its sensor saw).")
    for cls in view.detects:
        if not _is_ifc_class(cls):
            raise _fail(f"{where}: twin:detects {cls!r} is not an IFC class name.")
    if not view.detects:
        raise _fail(f"{where} has no twin:detects (the IFC classes its detector reports).")
    return view


def check_observation(observation: Observation, *, limits: Limits) -> Observation:
    """``observation`` if it may go to the twin: at least one element or a view, at most
    ``limits.elements_per_observation`` elements, each report and the view checked
    (:func:`check_report`, :func:`check_view`); ObservationError naming the first problem."""
    n = len(observation.reports)
    if n > limits.elements_per_observation:
        raise _fail(
            f"Observation describes {n} elements, more than the {limits.elements_per_observation} allowed."
        )
    if n == 0 and observation.view is None:
        raise _fail("Observation describes no element.")
    if observation.view is not None:
        check_view(observation.view)
    for report in observation.reports:
        check_report(report, limits=limits)
    return observation


LimitsKey = tuple[object, ...]


@functools.lru_cache(maxsize=8)
def limits_key(limits: Limits) -> LimitsKey:
    """Every value of ``limits``, in order: what two processes compare to know that they check alike."""
    return tuple(limits.model_dump().values())


@dataclass(frozen=True, slots=True)
class Checked:
    """An observation that passed :func:`check_observation` where it was made, under the limits whose
    :func:`limits_key` is ``limits`` (made by :func:`checked`)."""

    observation: Observation
    limits: LimitsKey

    def passed(self, limits: Limits) -> bool:
        """Whether it passed the checks of ``limits`` (the same values): nothing to check again."""
        return self.limits == limits_key(limits)

    def __reduce__(self) -> tuple[type[Checked], tuple[Observation, LimitsKey]]:
        """A call with its fields (one per array from an ingest worker; see :mod:`twin.records`)."""
        return (Checked, (self.observation, self.limits))


def checked(observation: Observation, *, limits: Limits) -> Observation | Checked:
    """``observation`` as :class:`Checked` if it passes :func:`check_observation`, else as it is (the
    writer checks it again and refuses it, with the same message)."""
    try:
        check_observation(observation, limits=limits)
    except ObservationError:
        return observation
    return Checked(observation, limits_key(limits))
