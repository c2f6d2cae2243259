"""Lanes along the middle of free space: the medial axis of a free mask, pruned, traced into chains.

The skeleton (scikit-image's ``skeletonize``) of a free mask keeps the topology of free space: one
connected skeleton per connected free region, passing midway between obstacles. Its pixels of degree
other than two (junctions, dead ends) and the pixels the caller forces (door crossings, a space's
most interior point, where a waypoint attaches) are **nodes**; the runs of pixels between two nodes
are **chains**. Short spurs (a dead end closer to its junction than about that junction's clearance:
the skeleton's answer to a bumpy wall) are pruned first; spurs into corners, dead-end corridors and
rooms stay.

Example::

    skeleton = pruned_skeleton(free, clearance)
    nodes, chains = trace(skeleton, forced)     # node pixels, and each chain's pixels in order
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage
from skimage.morphology import skeletonize

from twin.routes.lines import BoolArray, FloatArray, segments_free

IntArray = npt.NDArray[np.int64]

_OFFSETS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
_RING = np.ones((3, 3), dtype=np.int32)
_RING[1, 1] = 0
SPUR_FACTOR = 1.2
"""A dead end is pruned when its spur is shorter than this many times its junction's clearance."""


@dataclass(frozen=True, slots=True)
class Chain:
    """A run of skeleton pixels from node ``start`` to node ``end`` (flat indices), in order, both
    ends included: ``pixels[0]`` is a pixel of node ``start``, ``pixels[-1]`` one of node ``end``."""

    start: int
    end: int
    pixels: IntArray

    def length(self, width: int) -> float:
        """The chain's length in cells (diagonal steps count sqrt 2)."""
        rc = np.stack(np.divmod(self.pixels, width), axis=1)
        return float(np.hypot(*np.diff(rc, axis=0).T).sum()) if len(rc) > 1 else 0.0


def skeleton_of(free: BoolArray) -> BoolArray:
    """The medial-axis skeleton of ``free`` (``(h, w) bool``), one pixel wide, 8-connected."""
    skeleton: BoolArray = skeletonize(free)  # type: ignore[no-untyped-call]
    return skeleton & free


def degree(skeleton: BoolArray) -> IntArray:
    """``(h, w)``: each skeleton pixel's number of 8-neighbours on the skeleton (0 off it)."""
    deg = ndimage.convolve(skeleton.astype(np.int32), _RING, mode="constant")
    out: IntArray = np.where(skeleton, deg, 0).astype(np.int64)
    return out


def pruned_skeleton(free: BoolArray, clearance: FloatArray, *, rounds: int = 2) -> BoolArray:
    """The skeleton of ``free`` without short spurs.

    Args:
        free: ``(h, w) bool``, the cells a robot's centre may be in.
        clearance: ``(h, w) float``, each cell's distance to the nearest blocked cell, in cells.
        rounds: pruning passes (a pass can leave a new short spur where two met).
    """
    skeleton = skeleton_of(free)
    w = skeleton.shape[1]
    for _ in range(rounds):
        nodes, chains = trace(skeleton)
        deg_of = _node_degrees(chains)
        ends = {n for n, pixels in nodes.items() if len(pixels) == 1 and deg_of.get(n, 0) == 1}
        remove: list[IntArray] = []
        for chain in chains:
            tip, base = (chain.start, chain.end) if chain.start in ends else (chain.end, chain.start)
            if tip not in ends or deg_of.get(base, 0) < 3:
                continue
            reach = clearance.flat[nodes[base][0]]
            if chain.length(w) < SPUR_FACTOR * reach:
                remove.append(chain.pixels[:-1] if tip == chain.start else chain.pixels[1:])
        if not remove:
            break
        skeleton = skeleton.copy()
        skeleton.flat[np.concatenate(remove)] = False  # what is left of a thin skeleton stays thin
    return skeleton


def _node_degrees(chains: list[Chain]) -> dict[int, int]:
    deg: dict[int, int] = {}
    for c in chains:
        deg[c.start] = deg.get(c.start, 0) + 1
        deg[c.end] = deg.get(c.end, 0) + 1
    return deg


def trace(skeleton: BoolArray, forced: IntArray | None = None) -> tuple[dict[int, IntArray], list[Chain]]:
    """The skeleton's nodes and chains.

    Nodes are the connected groups of pixels of degree other than 2, and each ``forced`` pixel (flat
    indices of skeleton pixels) on its own; a node is named by its first pixel (flat index) and maps
    to its pixels. A loop without a node gets one. Chains of one step between two pixels of the same
    node are dropped.
    """
    h, w = skeleton.shape
    deg = degree(skeleton)
    is_node = skeleton & (deg != 2)
    forced_set: set[int] = set()
    if forced is not None and len(forced):
        forced = np.asarray(forced, dtype=np.int64)
        forced = forced[skeleton.flat[forced]]
        forced_set = {int(p) for p in forced}
    node_of = np.full(h * w, -1, dtype=np.int64)
    nodes: dict[int, IntArray] = {}
    labels, count = ndimage.label(is_node, structure=np.ones((3, 3), dtype=np.int32))
    if count:
        flat = labels.ravel()
        idx = np.flatnonzero(flat)
        order = np.argsort(flat[idx], kind="stable")
        idx = idx[order]
        bounds = np.searchsorted(flat[idx], np.arange(1, count + 2))
        for k in range(count):
            pixels = idx[bounds[k] : bounds[k + 1]]
            pixels = pixels[~np.isin(pixels, list(forced_set))] if forced_set else pixels
            if len(pixels):
                nodes[int(pixels[0])] = pixels
                node_of[pixels] = pixels[0]
    for p in forced_set:
        nodes[p] = np.array([p], dtype=np.int64)
        node_of[p] = p
    chains: list[Chain] = []
    visited = np.zeros(h * w, dtype=np.bool_)
    sk = skeleton.ravel()

    def neighbours(p: int) -> list[int]:
        r, c = divmod(p, w)
        out = []
        for dr, dc in _OFFSETS:
            rr, cc = r + dr, c + dc
            if 0 <= rr < h and 0 <= cc < w and sk[rr * w + cc]:
                out.append(rr * w + cc)
        return out

    def walk(start_pixel: int, first: int) -> None:
        path = [start_pixel, first]
        prev, cur = start_pixel, first
        while node_of[cur] < 0:
            visited[cur] = True
            options = [q for q in neighbours(cur) if q != prev and not visited[q] and q not in path[-3:]]
            if not options:
                options = [q for q in neighbours(cur) if q != prev and node_of[q] >= 0]
                if not options:
                    return  # a broken run (cannot happen on a thinned skeleton): dropped
            # prefer a node, then a 4-neighbour (diagonal corner-cutting pixels are later in the run)
            options.sort(key=lambda q: (node_of[q] < 0, abs(q - cur) not in (1, w)))
            prev, cur = cur, options[0]
            path.append(cur)
        a, b = int(node_of[start_pixel]), int(node_of[cur])
        if a == b and len(path) <= 3:
            return
        chains.append(Chain(a, b, np.array(path, dtype=np.int64)))

    for node, pixels in list(nodes.items()):
        for p in pixels:
            for q in neighbours(int(p)):
                if node_of[q] >= 0:
                    if node_of[q] != node and int(p) < q:
                        chains.append(Chain(node, int(node_of[q]), np.array([p, q], dtype=np.int64)))
                    continue
                if not visited[q]:
                    walk(int(p), q)
    rest = np.flatnonzero(sk & ~visited & (node_of < 0))
    while len(rest):  # loops without a node: the first pixel becomes one
        p = int(rest[0])
        nodes[p] = np.array([p], dtype=np.int64)
        node_of[p] = p
        visited[p] = True
        nb = [q for q in neighbours(p) if not visited[q]]
        if nb:
            walk(p, nb[0])
        rest = rest[~visited[rest] & (node_of[rest] < 0)]
    return nodes, chains


def simplify(points: FloatArray, free: BoolArray, *, tolerance: float) -> IntArray:
    """Indices of ``points`` (``(n, 2)`` cell coordinates, a chain in order) to keep: a Douglas-Peucker
    simplification within ``tolerance`` cells whose every segment is free."""
    n = len(points)
    if n <= 2:
        return np.arange(n, dtype=np.int64)
    keep = np.zeros(n, dtype=np.bool_)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        a, b = points[i], points[j]
        seg = b - a
        norm = float(np.hypot(*seg))
        inner = points[i + 1 : j]
        if norm == 0.0:
            dist = np.hypot(*(inner - a).T)
        else:
            dist = np.abs(seg[0] * (inner[:, 1] - a[1]) - seg[1] * (inner[:, 0] - a[0])) / norm
        k = int(np.argmax(dist))
        if dist[k] <= tolerance and segments_free(free, a[None], b[None])[0]:
            continue
        m = i + 1 + k
        keep[m] = True
        stack += [(i, m), (m, j)]
    return np.flatnonzero(keep)
