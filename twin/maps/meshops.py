"""Mesh topology: watertightness, consistent face orientation, and surfaces that close around a volume.

A closed mesh is filled when sliced, with the winding rule, which needs every face oriented
consistently (each edge walked once in each direction). Exporters do not always deliver that, so
:func:`orient_faces` repairs it where the surface allows. A mesh that is not watertight may still
close around a volume up to T-junctions (:func:`closes_around`): a surface model whose faces enclose
a lift's car is then filled like a solid.

Example::

    faces = orient_faces(faces) if is_edge_closed(faces) and not is_closed(faces) else faces
"""

from __future__ import annotations

from collections import deque
from itertools import pairwise

import numpy as np
import numpy.typing as npt

from twin.tolerances import TOLERANCES, Tolerances

IntArray = npt.NDArray[np.int32]
_SHIFT = 0.318309886  # rounding grids shifted off round numbers (model coordinates often are)


def _edges(faces: npt.NDArray[np.integer]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    f = faces.astype(np.int64)
    return np.concatenate([f[:, 0], f[:, 1], f[:, 2]]), np.concatenate([f[:, 1], f[:, 2], f[:, 0]])


def is_edge_closed(faces: IntArray) -> bool:
    """True if every undirected edge of ``faces`` ``(m, 3) int`` is used by exactly two faces."""
    if faces.size == 0:
        return False
    a, b = _edges(faces)
    n = int(faces.max()) + 1
    keys = np.sort(np.minimum(a, b) * n + np.maximum(a, b))
    if len(keys) % 2:
        return False
    # sorted keys must come in pairs: k0 == k1 != k2 == k3 != ...
    return bool((keys[0::2] == keys[1::2]).all() and (keys[2::2] != keys[1:-1:2]).all())


def is_closed(faces: IntArray) -> bool:
    """True if ``faces`` bounds a volume, consistently oriented: every directed edge (a, b) occurs as
    often as its reverse (b, a). The vertices must be welded for this to mean solid.

    Usually each edge is walked once each way; an element made of solids that touch along an edge (the
    treads of a spiral stair) walks that edge twice each way, and still has a winding number, so it
    still fills when sliced."""
    if faces.size == 0:
        return False
    a, b = _edges(faces)
    n = int(faces.max()) + 1
    return bool(np.array_equal(np.sort(a * n + b), np.sort(b * n + a)))


def are_closed(faces: list[IntArray]) -> npt.NDArray[np.bool_]:
    """:func:`is_closed` of each of many meshes' ``faces``, in one vectorised pass: ``(len(faces),) bool``.

    The meshes' vertex indices are offset apart so that their directed edges never meet; sorted, the
    edges of each mesh then lie in one block, the same block for the edges and their reverses.
    """
    out = np.zeros(len(faces), dtype=bool)
    sizes = np.array([len(f) for f in faces], dtype=np.int64)
    if not sizes.any():
        return out
    tops = np.array([int(f.max()) + 1 if len(f) else 0 for f in faces], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(tops)[:-1]])
    every = np.concatenate([f for f in faces if len(f)]).astype(np.int64)
    every += np.repeat(offsets[sizes > 0], sizes[sizes > 0])[:, None]
    a, b = _edges(every)
    n = int(tops.sum())
    mismatch = np.nonzero(np.sort(a * n + b) != np.sort(b * n + a))[0]
    ends = np.cumsum(3 * sizes)  # the edge blocks, in mesh order (a mesh's keys all share its offsets)
    out[:] = sizes > 0
    out[np.searchsorted(ends, mismatch, side="right")] = False
    return out


def orient_faces(faces: IntArray) -> IntArray | None:
    """Flip faces of an edge-closed mesh so it becomes consistently oriented, per connected shell.

    Returns the repaired ``(m, 3) int32`` faces, or None when the surface is not orientable or not
    edge-closed. Each shell keeps the orientation of its first face (a fully inverted shell still
    fills: the winding number is -1 instead of 1).
    """
    if not is_edge_closed(faces):
        return None
    m = len(faces)
    a, b = _edges(faces)
    n = int(faces.max()) + 1
    keys = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(keys, kind="stable")
    first, second = order[0::2], order[1::2]  # the two uses of each undirected edge
    face_of = np.arange(3 * m) % m
    # two faces sharing an edge agree if they walk it in opposite directions
    parity = (a[first] == a[second]).astype(np.int8)  # 1: same direction, one of them must flip
    f1, f2 = face_of[first], face_of[second]
    # every face has exactly three neighbours (one per edge): sort the pairs by face into (m, 3) tables
    by_face = np.argsort(np.concatenate([f1, f2]), kind="stable")
    nbr = np.concatenate([f2, f1])[by_face].reshape(m, 3)
    par = np.concatenate([parity, parity])[by_face].reshape(m, 3)
    flip: list[int] = [-1] * m  # a breadth-first walk over the face graph, per shell
    nbr_l: list[list[int]] = nbr.tolist()
    par_l: list[list[int]] = par.tolist()
    for start in range(m):
        if flip[start] >= 0:
            continue
        flip[start] = 0
        queue = deque([start])
        while queue:
            face = queue.popleft()
            for other, p in zip(nbr_l[face], par_l[face], strict=True):
                want = flip[face] ^ p
                if flip[other] < 0:
                    flip[other] = want
                    queue.append(other)
                elif flip[other] != want:
                    return None  # not orientable (e.g. a Moebius strip or a non-manifold fan)
    out = faces.astype(np.int32, copy=True)
    flipped = np.array(flip) == 1
    out[flipped] = out[flipped][:, ::-1]
    return out


def _odd_edges_on_lines(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.int64], tol: Tolerances
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The edges of ``faces`` used an odd number of times, ``(k, 2)`` vertex pairs (the smaller index
    first), with the line each lies on ``(k,)`` and the positions of their two ends along it
    ``(k, 2)``, in steps of ``tol.join_m``."""
    a, b = _edges(faces)
    n = int(faces.max()) + 1
    keys, counts = np.unique(np.minimum(a, b) * n + np.maximum(a, b), return_counts=True)
    odd = keys[counts % 2 == 1]
    pairs = np.stack([odd // n, odd % n], axis=1)
    p, q = vertices[pairs[:, 0]], vertices[pairs[:, 1]]
    d = q - p
    d /= np.linalg.norm(d, axis=1)[:, None]
    first = np.argmax(np.abs(d) > tol.join_m, axis=1)  # one direction per line: its first component > 0
    d *= np.sign(d[np.arange(len(d)), first])[:, None]
    tp, tq = (p * d).sum(axis=1), (q * d).sum(axis=1)
    foot = p - tp[:, None] * d  # the line's point nearest the origin
    line = np.floor(np.hstack([d, foot]) / tol.join_m + _SHIFT).astype(np.int64)
    _, group = np.unique(line, axis=0, return_inverse=True)
    ends = np.floor(np.stack([tp, tq], axis=1) / tol.join_m + _SHIFT).astype(np.int64)
    return pairs, group.reshape(-1), ends


def _proper(faces: IntArray) -> npt.NDArray[np.int64]:
    """``faces`` as int64, without those that collapse to a line or a point."""
    f = faces.astype(np.int64)
    proper: npt.NDArray[np.int64] = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    return proper


def closes_around(
    vertices: npt.NDArray[np.float64], faces: IntArray, *, tol: Tolerances = TOLERANCES
) -> bool:
    """True if the surface ``faces`` ``(m, 3) int`` over ``vertices`` ``(n, 3) float64`` (welded)
    closes around a volume: along every line, each point of the mesh's edges is covered by an even
    number of them.

    A watertight mesh uses each edge twice. A kernel that triangulates face by face leaves
    T-junctions (one face's edge ``a-c`` split at its neighbour's vertex ``b``): ``a-c``, ``a-b`` and
    ``b-c`` are used once each, yet cover their line twice. A surface with a border (a railing's ring
    of faces around a void, a lost face) covers its border once: not closed. Edge ends within
    ``tol.join_m`` along a line are one point, lines within it (direction and offset) are one line.
    Orientation is not looked at. Degenerate faces are ignored.
    """
    f = _proper(faces)
    if not len(f):
        return False
    _, group, ends = _odd_edges_on_lines(vertices, f, tol)
    # the parity of the cover along a line changes only at points where an odd number of edges end
    points = np.stack([np.tile(group, 2), ends.T.reshape(-1)], axis=1)
    _, ends_at = np.unique(points, axis=0, return_counts=True)
    return bool((ends_at % 2 == 0).all())


def seal_t_junctions(
    vertices: npt.NDArray[np.float64], faces: IntArray, *, tol: Tolerances = TOLERANCES
) -> IntArray:
    """``faces`` ``(m, 3)`` with every T-junction split: a surface that :func:`closes_around` a volume
    then uses each edge an even number of times (``(m', 3) int32``; degenerate faces dropped).

    A triangle whose edge ``a-c`` passes through vertices ``b1, b2, ...`` of its neighbours (within
    ``tol.join_m``) is replaced by the fan ``(a, b1, x), (b1, b2, x), ..., (bk, c, x)`` from its third
    vertex ``x``, in the triangle's own turning sense. The vertices are unchanged. Only the triangles
    at T-junctions are visited (in Python, one at a time): meant for the few meshes that need it.
    """
    f = _proper(faces)
    if not len(f):
        return f.astype(np.int32)
    pairs, group, ends = _odd_edges_on_lines(vertices, f, tol)
    on_line: dict[int, dict[int, int]] = {}  # line -> vertex -> its position along the line
    for (u, v), g, (eu, ev) in zip(pairs.tolist(), group.tolist(), ends.tolist(), strict=True):
        on_line.setdefault(g, {}).update({u: eu, v: ev})
    inner: dict[tuple[int, int], list[int]] = {}  # edge (u, v), u < v -> the vertices strictly inside, u to v
    for (u, v), g, (eu, ev) in zip(pairs.tolist(), group.tolist(), ends.tolist(), strict=True):
        lo, hi = min(eu, ev), max(eu, ev)
        inside = sorted((e, w) for w, e in on_line[g].items() if lo < e < hi)
        if inside:
            ordered = [w for _, w in inside]
            inner[(u, v)] = ordered if eu < ev else ordered[::-1]
    if not inner:
        return f.astype(np.int32)
    a, b = _edges(f)
    n = int(f.max()) + 1
    split = np.array([u * n + v for u, v in inner], dtype=np.int64)
    at = np.isin(np.minimum(a, b) * n + np.maximum(a, b), split).reshape(3, -1).any(axis=0)
    out: list[list[int]] = f[~at].tolist()
    todo = f[at].tolist()
    while todo:
        tri = todo.pop()
        for k in range(3):
            x, y, apex = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            mids = inner.get((x, y)) if x < y else (inner.get((y, x)) or [])[::-1]
            if mids:
                chain = [x, *mids, y]
                todo.extend([s, t, apex] for s, t in pairwise(chain))
                break
        else:
            out.append(tri)
    return np.array(out, dtype=np.int32)


def orient_shells(faces: IntArray) -> IntArray | None:
    """:func:`orient_faces` for meshes whose closed shells touch along edges (more than two faces on
    an edge: the bodies of a cabinet modelled as one surface model): the faces are split into shells
    at such edges, and each shell is oriented on its own. None when a shell is not edge-closed or not
    orientable."""
    if faces.size == 0:
        return None
    a, b = _edges(faces)
    m, n = len(faces), int(faces.max()) + 1
    keys = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(keys, kind="stable")
    _, first, counts = np.unique(keys[order], return_index=True, return_counts=True)
    two = first[counts == 2]
    f1, f2 = order[two] % m, order[two + 1] % m  # the two faces of each edge used exactly twice
    shell = list(range(m))  # union-find over those face pairs

    def root(i: int) -> int:
        while shell[i] != i:
            shell[i] = shell[shell[i]]
            i = shell[i]
        return i

    for i, j in zip(f1.tolist(), f2.tolist(), strict=True):
        ri, rj = root(i), root(j)
        if ri != rj:
            shell[max(ri, rj)] = min(ri, rj)
    label = np.array([root(i) for i in range(m)])
    out = faces.astype(np.int32, copy=True)
    for s in np.unique(label):
        mine = np.flatnonzero(label == s)
        oriented = orient_faces(out[mine])
        if oriented is None:
            return None
        out[mine] = oriented
    return out


def _shell_labels(faces: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.bool_]]:
    """Per face of ``faces (m, 3)``: its shell, the smallest face index of the faces reached across
    edges used by exactly two faces (shells touching along an edge, or at a vertex, stay apart), and
    whether that shell is closed on its own (each of its edges used by two of its faces; not a piece
    cut off where shells share a face). Vectorised: roots hooked to their smallest neighbour's root,
    then paths halved, until stable."""
    m = len(faces)
    a, b = _edges(faces)
    n = int(faces.max()) + 1
    keys = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(keys, kind="stable")
    k = keys[order]
    starts = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
    counts = np.diff(np.append(starts, len(k)))
    two = starts[counts == 2]
    f1, f2 = order[two] % m, order[two + 1] % m
    label = np.arange(m, dtype=np.int64)
    while True:
        r1, r2 = label[f1], label[f2]
        differ = r1 != r2
        if not differ.any():
            break
        low, high = np.minimum(r1, r2)[differ], np.maximum(r1, r2)[differ]
        np.minimum.at(label, high, low)  # hook the larger root under the smaller
        while True:  # then every face points at its root
            up = label[label]
            if np.array_equal(up, label):
                break
            label = up
    closed = np.ones(m, dtype=np.bool_)
    other = np.flatnonzero(counts != 2)
    if len(other):  # the edges not used twice: each shell must use them twice itself
        uses = np.repeat(other, counts[other])
        rows = order[
            np.concatenate([np.arange(s, s + c) for s, c in zip(starts[other], counts[other], strict=True)])
        ]
        shell = label[rows % m]
        pair, per = np.unique(shell * len(starts) + uses, return_counts=True)
        closed[pair[per != 2] // len(starts)] = False
    return label, closed


def signed_volumes(meshes: list[tuple[npt.NDArray[np.float64], IntArray]]) -> npt.NDArray[np.float64]:
    """The signed volume of each mesh ``(vertices (n, 3), faces (m, 3))`` (positive when its faces turn
    outward; meaningful for closed meshes), about its first vertex: ``(len(meshes),) float64``. (Mesh by
    mesh: faster than stacking them, whose copies cost more than the sums.)"""
    out = np.zeros(len(meshes))
    for k, (v, f) in enumerate(meshes):
        if len(f):
            out[k] = float(_six_volumes(v - v[0], f.astype(np.int64)).sum()) / 6
    return out


def _stacked(
    meshes: list[tuple[npt.NDArray[np.float64], IntArray]],
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """All meshes' faces (offset into the stacked vertices), vertices (each mesh about its first
    vertex: rounding) and each face's mesh."""
    sizes = np.array([len(f) for _, f in meshes], dtype=np.int64)
    tops = np.array([len(v) for v, _ in meshes], dtype=np.int64)
    v_off = np.concatenate([[0], np.cumsum(tops)[:-1]])
    faces = np.concatenate([f.astype(np.int64) + o for (_, f), o in zip(meshes, v_off, strict=True)])
    verts = np.concatenate([v - v[0] if len(v) else v for v, _ in meshes])
    return faces, verts, np.repeat(np.arange(len(meshes)), sizes)


def _six_volumes(verts: npt.NDArray[np.float64], faces: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
    """Six times each face's signed volume with the origin (``p0 . (p1 x p2)``)."""
    p0, p1, p2 = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    out: npt.NDArray[np.float64] = (
        p0[:, 0] * (p1[:, 1] * p2[:, 2] - p1[:, 2] * p2[:, 1])
        + p0[:, 1] * (p1[:, 2] * p2[:, 0] - p1[:, 0] * p2[:, 2])
        + p0[:, 2] * (p1[:, 0] * p2[:, 1] - p1[:, 1] * p2[:, 0])
    )
    return out


def orient_outward(meshes: list[tuple[npt.NDArray[np.float64], IntArray]]) -> list[IntArray]:
    """The faces of each closed, consistently oriented mesh ``(vertices (n, 3), faces (m, 3))`` with
    every shell turned outward: a shell (faces joined across edges used by exactly two faces) that is
    closed on its own and whose signed volume is negative has its faces flipped. All meshes in one
    vectorised pass.

    Exporters and kernels may wind a closed shell either way (a surface model's face sets need not
    agree, :func:`orient_faces` keeps a shell's first face's turn); the fill's non-zero winding rule
    then lets a shell nested in, or overlapping, an oppositely wound one cancel it. Outward shells all
    count +1, so they unite; and the normals of points clouds point outward.
    """
    if not meshes or not sum(len(f) for _, f in meshes):
        return [f for _, f in meshes]
    faces, verts, _ = _stacked(meshes)
    label, closed = _shell_labels(faces)
    volume = np.bincount(label, weights=_six_volumes(verts, faces), minlength=len(faces))
    flip = (volume[label] < 0) & closed[label]
    f_off = np.concatenate([[0], np.cumsum([len(f) for _, f in meshes])])
    out = []
    for k, (_, f) in enumerate(meshes):
        mine = flip[f_off[k] : f_off[k + 1]]
        turned = f
        if mine.any():
            turned = f.copy()
            turned[mine] = f[mine][:, ::-1]
        out.append(turned)
    return out
