"""Check stored element meshes against the reference kernel (OpenCASCADE), element by element.

Two meshes of one element agree when their world bounding boxes are within ``bbox_m`` (1 cm) on
every side and, when both are closed, their volumes within ``volume_rel`` (1 %); open meshes (surfaces,
not solids) are compared by bounding box and area instead.

Example::

    model = read_model(path)
    for d in disagreements(path, model):
        print(d.guid, d.reason)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import ifcopenshell
import numpy as np

from adapters.ifc.geometry import start_meshing
from adapters.ifc.kernel_choice import REFERENCE_KERNEL
from twin.records import BuildingModel, Geometry


@dataclass(frozen=True, slots=True)
class Tolerance:
    """How far a mesh may be from the reference mesh of the same element."""

    bbox_m: float = 0.01
    volume_rel: float = 0.01
    area_rel: float = 0.01


@dataclass(frozen=True, slots=True)
class MeshMeasures:
    """World bounding box ``(lo, hi)``, signed volume (m3, meaningful when closed) and area (m2)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    volume_m3: float
    area_m2: float
    closed: bool


@dataclass(frozen=True, slots=True)
class Disagreement:
    """An element whose stored mesh differs from the reference kernel's, and how."""

    guid: str
    ifc_class: str
    kernel: str
    reason: str


def measure(geometry: Geometry) -> MeshMeasures:
    """Bounding box, volume and area of ``geometry`` in world coordinates (vectorised over triangles)."""
    v = geometry.world_vertices()
    t = v[geometry.mesh.faces]
    cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    volume = float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)
    lo, hi = v.min(axis=0), v.max(axis=0)
    return MeshMeasures(
        (float(lo[0]), float(lo[1]), float(lo[2])),
        (float(hi[0]), float(hi[1]), float(hi[2])),
        volume,
        float(np.linalg.norm(cross, axis=1).sum() / 2.0),
        geometry.mesh.closed,
    )


def compare(ours: MeshMeasures, reference: MeshMeasures, tol: Tolerance = Tolerance()) -> str | None:
    """None when ``ours`` agrees with ``reference``, else a sentence saying how they differ."""
    gap = float(
        max(
            np.abs(np.subtract(ours.lo, reference.lo)).max(), np.abs(np.subtract(ours.hi, reference.hi)).max()
        )
    )
    if gap > tol.bbox_m:
        return f"bounding box off by {gap * 100:.1f} cm"
    if ours.closed and reference.closed:
        rel = abs(ours.volume_m3 - reference.volume_m3) / max(abs(reference.volume_m3), 1e-12)
        if rel > tol.volume_rel:
            return f"volume {ours.volume_m3:.4g} m3 vs {reference.volume_m3:.4g} m3 ({rel:.1%})"
        return None
    rel = abs(ours.area_m2 - reference.area_m2) / max(reference.area_m2, 1e-12)
    if rel > tol.area_rel:
        kind = "open" if not ours.closed else "closed"
        return f"{kind} mesh, area {ours.area_m2:.4g} m2 vs {reference.area_m2:.4g} m2 ({rel:.1%})"
    return None


def reference_geometry(
    path: Path, guids: Sequence[str] | None = None, *, threads: int = 2
) -> dict[str, Geometry]:
    """The reference kernel's geometry of every element of ``path`` (or of ``guids``), by GlobalId."""
    f = ifcopenshell.open(str(path))
    products: list[Any] = list(f.by_type("IfcElement")) if guids is None else [f.by_guid(g) for g in guids]
    with start_meshing(f, products, kernels=(REFERENCE_KERNEL,), threads=threads) as job:
        result = job.result()
    by_id: Any = f.by_id
    return {str(by_id(pid).GlobalId): g for pid, g in result.geometry.items()}


def disagreements(
    path: Path, model: BuildingModel, *, tol: Tolerance = Tolerance(), threads: int = 2
) -> list[Disagreement]:
    """Every element of ``model`` (read from ``path``) whose mesh differs from the reference kernel's.

    An element the reference meshes and ``model`` does not (or the reverse) is a disagreement too.
    """
    reference = reference_geometry(path, threads=threads)
    out = []
    for e in model.elements:
        ref = reference.get(e.guid)
        if e.geometry is None and ref is None:
            continue
        if e.geometry is None or ref is None:
            missing = "no stored mesh" if e.geometry is None else "the reference kernel meshes nothing"
            out.append(Disagreement(e.guid, e.ifc_class, e.mesh_kernel, missing))
            continue
        differs = compare(measure(e.geometry), measure(ref), tol)
        if differs is not None:
            out.append(Disagreement(e.guid, e.ifc_class, e.mesh_kernel, differs))
    return out
