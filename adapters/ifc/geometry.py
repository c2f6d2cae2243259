"""Mesh IFC products with ifcopenshell's geometry iterator on every core, falling back between kernels.

The fast kernel (manifold, ~10x opencascade) meshes almost everything; the products it cannot mesh are
given to the next kernel, so no geometry is lost and no product is meshed twice. A kernel can also
*crash* the process on some models (manifold segfaults on the Duplex sample), so each kernel pass runs
in a child process (:mod:`adapters.ifc.kernel_child`) forked by this one, which streams shapes back
over a pipe that a thread drains: if the child dies or stalls, what it had not delivered goes to the
next kernel.

Parallelism is by processes, not by the iterator's own threads (with two threads, ifcopenshell 0.9's
iterator spends 35 % more CPU on Janesville and 5x more on a generated 12,000-element building). At most
``threads`` children run at once, each a single-threaded iterator over a *unit* of work (a set of
products and the kernels still to try). How long a product takes is not known beforehand (an extrusion
takes 0.1 ms, a B-rep with openings 10 ms), so the cores are kept busy by splitting: when a core
would idle, the child with the most work left (by its own pace so far) is asked to stop, and what it
had not meshed is dealt into two new units. Each split costs one more iterator start (10-70 ms),
so only work that would take longer than :data:`SPLIT_MIN_SECONDS` is split.

The first children also decide which of their products the reference kernel must mesh first
(:mod:`adapters.ifc.kernel_choice`), so that meshing starts as soon as the file is open; what they
route goes to reference-kernel children started beside them. Products whose bodies map one
representation map are dealt to one child (:func:`shared_maps`): an iterator meshes a shared map once.

Meshes are local (``use-world-coords`` off) with the placement as a separate matrix; instances that
share a representation share one :class:`~twin.records.Mesh` (decoded once per kernel).

Example::

    with start_meshing(f, products, kernels=("manifold", "opencascade")) as job:
        ...                                   # read the structure meanwhile
        result = job.result()
    geometry = result.geometry[product.id()]
"""

from __future__ import annotations

import heapq
import logging
import multiprocessing as mp
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import TracebackType
from typing import Any, Self

from adapters.ifc.errors import ENTITY_ERRORS
from adapters.ifc.kernel_child import ROUTED, STOPPED, Shape, run_kernel
from adapters.ifc.kernel_choice import REFERENCE_KERNEL
from twin.records import Geometry, Mesh

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
DEFAULT_KERNELS = ("manifold", "opencascade")
STALL_SECONDS = 300.0
SPLIT_MIN_SECONDS = 0.25
"""A child is split only when its work left, at its pace so far, would take longer than this."""
SPLIT_MIN_PRODUCTS = 8
INSTANCE_WEIGHT = 0.4
"""What meshing one more instance of a shared representation map costs, against a body of its own
(62 against 160 us on the generated 12,000-element building): how :func:`_shards` weighs a group."""


@dataclass(slots=True)
class MeshResult:
    """Geometry by product id (``ifc.id()``), which kernel meshed what, and what no kernel could mesh.

    ``fallbacks`` are the products meshed by another kernel than the first of their route.
    """

    geometry: dict[int, Geometry] = field(default_factory=dict)
    kernel_of: dict[int, str] = field(default_factory=dict)
    unmeshed: list[int] = field(default_factory=list)
    fallbacks: set[int] = field(default_factory=set)
    children: int = 0
    """How many kernel children ran (splits and fallbacks included)."""
    splits: int = 0
    """How many children were stopped to share what they had left."""


@dataclass(frozen=True, slots=True)
class _Unit:
    """Products for one child: ``kernels[0]`` meshes them, the rest are tried in turn on what it leaves.

    ``first`` is the first kernel of the products' route: meshed by another one, a product is a fallback.
    With ``routing``, the child first names the elements the reference kernel must mesh first and leaves
    them (:data:`~adapters.ifc.kernel_child.ROUTED`).
    """

    ids: frozenset[int]
    kernels: tuple[str, ...]
    first: str
    routing: bool = False


class _KernelRun:
    """One child meshing one unit; a thread drains its pipe into ``on_batch``, then calls ``on_end``."""

    def __init__(
        self,
        f: Any,
        unit: _Unit,
        on_batch: Callable[[_KernelRun, list[Shape]], None],
        on_end: Callable[[_KernelRun], None],
        on_routed: Callable[[_KernelRun, list[int], list[tuple[int, str]]], None],
    ) -> None:
        ctx = mp.get_context("fork")
        self.unit = unit
        self.kernel = unit.kernels[0]
        self.pending = set(unit.ids)  # not meshed (yet) by this run
        self.meshes: dict[str, Mesh] = {}  # geometry id -> mesh, of this child
        self.delivered = 0
        self.started = time.monotonic()
        self.finished = False  # the child went through all its products
        self.stopped = False  # the child stopped when asked
        self.stopping = False
        self.routed: bool | None = None if unit.routing else False  # None: its routing is yet to come
        self.error: str | None = None
        self._conn, child_end = ctx.Pipe(duplex=False)
        self._stop = ctx.RawValue("b", 0)
        self._child = ctx.Process(
            target=run_kernel,
            args=(f, sorted(unit.ids), self.kernel, child_end, self._stop),
            kwargs={"routing": unit.routing},
            daemon=True,
        )
        self._child.start()
        child_end.close()
        self._on_batch, self._on_end, self._on_routed = on_batch, on_end, on_routed
        self._thread = threading.Thread(target=self._drain, name=f"twin-mesh-{self.kernel}", daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        try:
            while True:
                if not self._conn.poll(STALL_SECONDS):
                    self.error = f"no shape for {STALL_SECONDS:.0f} s (stalled)"
                    self._child.kill()
                    break
                try:
                    message = self._conn.recv()
                except (EOFError, OSError):
                    break
                if message is None:
                    self.finished = True
                    break
                if message == STOPPED:
                    self.stopped = True
                    break
                if isinstance(message, str):
                    self.error = message
                    break
                if isinstance(message, tuple) and message[0] == ROUTED:
                    self._on_routed(self, message[1], message[2])
                    continue
                self.delivered += len(message)
                self._on_batch(self, message)
        finally:
            self._conn.close()
            self._child.join()
            self._on_end(self)

    def seconds_left(self, now: float) -> float:
        """How long the products not yet delivered would take at this child's pace so far (inf before
        its first shape)."""
        if not self.delivered:
            return float("inf")
        return len(self.pending) * (now - self.started) / self.delivered

    def stop(self) -> None:
        """Ask the child to stop after its current shape (what it meshed is sent first)."""
        self.stopping = True
        self._stop.value = 1

    def kill(self) -> None:
        if self._child.is_alive():
            self._child.kill()

    def join(self) -> None:
        self._thread.join()

    @property
    def exitcode(self) -> int | None:
        return self._child.exitcode


def _shards(ids: Collection[int], n: int, together: Mapping[int, int] | None = None) -> list[frozenset[int]]:
    """``ids`` dealt into ``n`` sets of near-equal work; empty sets are left out.

    Ids with the same ``together`` key (products whose bodies map one representation map) go to one
    set, heaviest group first to the lightest set (a group weighs one body and
    :data:`INSTANCE_WEIGHT` for each further instance), unless the group weighs more than a set's
    share (then a mesh more is cheaper than unequal sets): an iterator meshes a shared map once, so two
    children that each get some of its instances mesh it twice (on Janesville, dealing its 1,139
    manifold products round-robin cost 2.2 s of CPU in two children against 1.6 s in one). The other
    ids are dealt round-robin in id order, a set that is a body ahead of the lightest skipping its turn
    (contiguous ranges are unequal work: the file groups products by kind).
    """
    n = max(n, 1)
    together = together or {}
    groups: dict[int, list[int]] = {}
    for i in ids:
        key = together.get(i)
        if key is not None:
            groups.setdefault(key, []).append(i)
    weight = {k: 1.0 + INSTANCE_WEIGHT * (len(g) - 1) for k, g in groups.items()}
    share = (len(ids) - sum(len(g) for g in groups.values()) + sum(weight.values())) / n
    kept = [k for k in groups if weight[k] <= share]  # a heavier group is dealt like the rest
    sets: list[list[int]] = [[] for _ in range(n)]
    loads = [(0.0, k) for k in range(n)]  # (weight so far, set): a heap
    for key in sorted(kept, key=lambda k: (-weight[k], k)):
        load, k = heapq.heappop(loads)
        sets[k].extend(sorted(groups[key]))
        heapq.heappush(loads, (load + weight[key], k))
    grouped = {i for k in kept for i in groups[k]}
    weights = [0.0] * n
    for load, k in loads:
        weights[k] = load
    k = 0
    for i in sorted(i for i in ids if i not in grouped):  # round-robin, skipping a set ahead by a body
        while weights[k] >= min(weights) + 1.0:
            k = (k + 1) % n
        sets[k].append(i)
        weights[k] += 1.0
        k = (k + 1) % n
    return [frozenset(x) for x in sets if x]


def shared_maps(f: Any) -> dict[int, int]:
    """Product id -> the id of a representation map one of its representations maps (``IfcMappedItem``;
    the last found where there are several), for the products that have one: instances of one type
    share it. Found from the mapped items up (a few ms on 12,000 elements); only a hint for grouping
    work, {} if the file's references cannot be followed."""
    out: dict[int, int] = {}
    try:
        for item in f.by_type("IfcMappedItem"):
            source = item[0]
            if source is None:
                continue
            for representation in f.get_inverse(item):
                for shape in f.get_inverse(representation):
                    if shape.is_a("IfcProductDefinitionShape"):
                        for product in f.get_inverse(shape):
                            if product.is_a("IfcProduct"):  # not a shape aspect
                                out[product.id()] = source.id()
    except ENTITY_ERRORS:  # a malformed file
        return {}
    return out


class MeshingJob:
    """Meshing in progress, on up to ``threads`` children; :meth:`result` waits for all of it.

    Products whose body the fast kernel gets wrong (:func:`~adapters.ifc.kernel_choice.reference_reason`)
    go to the reference kernel first; the others to ``kernels`` in order. Those products are either
    given (``routed``) or, with ``route``, named by the first children themselves: each routes its own
    share while the others start, and what they route goes to reference-kernel children started beside
    them. Both routes run at once, each in as many children as its share of the products gives (at
    least one), and children are split to keep every core busy (see the module's docstring).
    Use it as a context manager: leaving it on an error (or Ctrl-C) kills the kernel processes.
    """

    def __init__(
        self,
        f: Any,
        products: Sequence[Any],
        *,
        kernels: Sequence[str],
        threads: int,
        progress: Progress | None,
        routed: Sequence[Any] = (),
        route: bool = False,
        skip: Collection[int] = (),
        split_min_s: float = SPLIT_MIN_SECONDS,
    ) -> None:
        self._f = f
        self._split_min_s = split_min_s
        self._progress = progress
        self._threads = max(threads, 1)
        with_body = {p.id() for p in products if getattr(p, "Representation", None) is not None}
        self._skipped = sorted(with_body & set(skip))
        with_body -= set(skip)
        self._with_body = with_body
        self._result = MeshResult()
        self._warned: set[tuple[int, str]] = set()
        self._shared: dict[tuple[str, str, bool], Mesh] = {}  # (kernel, geometry id, solid) -> the mesh
        self._cond = threading.Condition()
        self._queue: deque[_Unit] = deque()
        self._running: list[_KernelRun] = []
        self._failure: BaseException | None = None
        self._cancelled = False
        self._arrived: queue.SimpleQueue[list[int] | None] = queue.SimpleQueue()
        self._together = shared_maps(f) if self._threads > 1 else {}
        chain = tuple(kernels)
        self._reference_first = (REFERENCE_KERNEL, *(k for k in chain if k != REFERENCE_KERNEL))
        self._routes_due = 0  # routing children that have not yet named what they route
        self._routed_by_children: set[int] = set()
        if route and not routed and REFERENCE_KERNEL in chain[1:]:  # the children route
            self._queue.extend(
                _Unit(s, chain, chain[0], routing=True)
                for s in _shards(with_body, self._threads, self._together)
            )
            self._routes_due = slots = len(self._queue)
        else:
            routed_ids = {p.id() for p in routed} & with_body if REFERENCE_KERNEL in chain else set()
            rest_ids = with_body - routed_ids
            n_routed = n_rest = self._threads
            apart = False
            if routed_ids and rest_ids and self._threads > 1:
                n_routed, apart = self._reference_children(len(routed_ids))
                n_rest = self._threads if apart else max(1, self._threads - n_routed)
            for ids, path, n in ((routed_ids, self._reference_first, n_routed), (rest_ids, chain, n_rest)):
                if path:  # no kernels: nothing is meshed
                    self._queue.extend(_Unit(s, path, path[0]) for s in _shards(ids, n, self._together))
            slots = n_routed + n_rest if apart else self._threads
        with self._cond:
            self._schedule(slots=slots)
            if not self._running:
                self._arrived.put(None)

    def _reference_children(self, count: int) -> tuple[int, bool]:
        """(how many children ``count`` products of the reference route get, whether they run apart,
        beside a full set of children for the rest): their share of the cores, but at least one; a
        share that rounds to none (a few costly products) runs apart, and whichever ends first has
        the other split. For more than one core."""
        share = round(self._threads * count / len(self._with_body))
        return (1, True) if share == 0 else (min(self._threads - 1, share), False)

    def partial(self) -> MeshResult:
        """The result as it grows: read an entry only once :meth:`arrivals` has named its product."""
        return self._result

    def arrivals(self) -> Iterator[int]:
        """The ids of the products as they get their geometry (in :attr:`MeshResult.geometry`), until the
        meshing ends; read it from one thread only, once."""
        while (batch := self._arrived.get()) is not None:
            yield from batch

    # --- called from the drain threads, under no lock ---------------------------------------------
    def _take(self, run: _KernelRun, batch: list[Shape]) -> None:
        result, arrived = self._result, []
        with self._cond:
            for pid, geom_id, mesh, placement, solid, refused, note in batch:
                if note is not None:
                    self._warn_once(pid, note)
                if mesh is not None:  # an empty mesh is no mesh: the next kernel tries
                    run.meshes[geom_id] = self._shared.setdefault((run.kernel, geom_id, mesh.solid), mesh)
                known = run.meshes.get(geom_id)
                if pid not in run.pending or known is None:
                    continue
                if placement is None:  # left pending: the next kernel tries, then it is unmeshed
                    self._warn_once(pid, f"{refused}; its geometry is refused")
                    continue
                if known.solid != solid:  # instances of one representation told apart by their products
                    key = (run.kernel, geom_id, solid)
                    known = self._shared.setdefault(key, replace(known, solid=solid))
                result.geometry[pid] = Geometry(known, placement)
                arrived.append(pid)
                result.kernel_of[pid] = run.kernel
                if run.kernel != run.unit.first:
                    result.fallbacks.add(pid)
                run.pending.discard(pid)
            if self._progress is not None:  # under the lock: the counts reach it in order
                self._progress(len(result.geometry), len(self._with_body))
        if arrived:
            self._arrived.put(arrived)

    def _routed_by(self, run: _KernelRun, ids: list[int], notes: list[tuple[int, str]]) -> None:
        """A routing child named the products the reference kernel meshes first: once every routing
        child has, they go to reference-kernel children started beside the running ones."""
        with self._cond:
            try:
                for pid, note in notes:
                    self._warn_once(pid, note)
                run.pending.difference_update(ids)
                self._routed_by_children.update(ids)
                run.routed = True
                self._route_known()
            except BaseException as err:  # handed to result(), as in _ended
                self._failure = err
                self._arrived.put(None)
                self._cond.notify_all()

    def _route_known(self) -> None:
        """One routing child fewer to wait for (under the lock); after the last, start the routed."""
        self._routes_due -= 1
        ids = self._routed_by_children
        if self._routes_due or not ids or self._cancelled:
            return
        n = self._reference_children(len(ids))[0] if self._threads > 1 else 1  # beside the running ones
        path = self._reference_first
        self._queue.extend(_Unit(s, path, path[0]) for s in _shards(ids, n, self._together))
        self._schedule(slots=len(self._running) + n if self._threads > 1 else 0)

    def _warn_once(self, pid: int, what: str) -> None:
        if (pid, what) not in self._warned:
            self._warned.add((pid, what))
            product = self._f.by_id(pid)
            log.warning("%s %s %s: %s", product.is_a(), product.GlobalId, product.Name or "", what)

    def _ended(self, run: _KernelRun) -> None:
        with self._cond:
            try:
                self._running.remove(run)
                if run.routed is None:  # ended before naming what it routes: the rest go on without
                    run.routed = False
                    self._route_known()
                left, unit = frozenset(run.pending), run.unit
                if self._cancelled:  # killed on purpose: nothing to report or to hand on
                    pass
                elif run.stopped:  # split: what it left goes to two children, with the same kernel
                    self._result.splits += 1
                    self._queue.extendleft(
                        _Unit(s, unit.kernels, unit.first) for s in _shards(left, 2, self._together)
                    )
                else:
                    self._report(run, len(left))
                    if left and len(unit.kernels) > 1:
                        self._queue.append(_Unit(left, unit.kernels[1:], unit.first))
                if not self._cancelled:
                    self._schedule()
            except BaseException as err:  # handed to result()
                self._failure = err
            if self._failure is not None or not (self._running or self._queue):
                self._arrived.put(None)
            self._cond.notify_all()

    @staticmethod
    def _report(run: _KernelRun, left: int) -> None:
        if run.error is not None:
            log.warning(
                "Geometry kernel %s failed: %s; %d product(s) left for the next kernel",
                run.kernel,
                run.error,
                left,
            )
        elif not run.finished:
            log.warning(
                "Geometry kernel %s crashed (exit code %s); %d product(s) left for the next kernel",
                run.kernel,
                run.exitcode,
                left,
            )
        elif left:
            log.info("%d product(s) not meshed by %s; trying the next kernel", left, run.kernel)

    # --- scheduling (under the condition's lock) --------------------------------------------------
    def _schedule(self, slots: int = 0) -> None:
        """Start queued units on free cores (``slots`` children at most, if more than the cores); with
        a core free and nothing queued, split the child with the most work left."""
        slots = max(self._threads, slots)
        while self._queue and len(self._running) < slots:
            self._running.append(
                _KernelRun(self._f, self._queue.popleft(), self._take, self._ended, self._routed_by)
            )
            self._result.children += 1
        busy = [r for r in self._running if len(r.unit.ids) >= SPLIT_MIN_PRODUCTS]  # a few fallbacks: no
        if self._queue or len(busy) >= self._threads:
            return
        now = time.monotonic()
        candidates = [r for r in busy if not r.stopping and len(r.pending) >= SPLIT_MIN_PRODUCTS]
        if candidates:
            slowest = max(candidates, key=lambda r: r.seconds_left(now))
            if slowest.seconds_left(now) > self._split_min_s:
                slowest.stop()

    def result(self) -> MeshResult:
        """Wait for every kernel and fallback; return everything."""
        with self._cond:
            while (self._running or self._queue) and self._failure is None:
                self._cond.wait(0.1)
                if not self._queue:
                    self._schedule()  # a child that has now found its pace may be worth splitting
            if self._failure is not None:
                raise self._failure
            result = self._result
            meshed = set(result.geometry)
            result.unmeshed = sorted([*self._skipped, *(pid for pid in self._with_body if pid not in meshed)])
            total = len(self._with_body)
        if self._progress is not None and total:
            self._progress(total, total)
        return result

    def cancel(self) -> None:
        with self._cond:
            self._cancelled = True
            self._queue.clear()
            running = list(self._running)
            if not running:
                self._arrived.put(None)
        for run in running:
            run.kill()
        for run in running:
            run.join()

    def release(self) -> None:
        """Cancel what still runs and let go of the file (:meth:`partial` stays)."""
        self.cancel()
        self._f = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.cancel()


def start_meshing(
    f: Any,
    products: Sequence[Any],
    *,
    kernels: Sequence[str] = DEFAULT_KERNELS,
    threads: int = 2,
    progress: Progress | None = None,
    routed: Sequence[Any] = (),
    route: bool = False,
    skip: Collection[int] = (),
    split_min_s: float = SPLIT_MIN_SECONDS,
) -> MeshingJob:
    """Start meshing ``products`` (ifcopenshell entities) in the background; see :class:`MeshingJob`.

    ``routed`` products (a subset) go to the reference kernel first, when it is among ``kernels``; with
    ``route`` (and no ``routed``), the children decide which (:mod:`adapters.ifc.kernel_choice`).
    Products whose id is in ``skip`` are not meshed: they are listed as unmeshed. ``threads`` is the
    number of cores to use: how many kernel children run at once. A child whose work left would take
    longer than ``split_min_s`` is split when a core idles.
    """
    return MeshingJob(
        f,
        products,
        kernels=kernels,
        threads=threads,
        progress=progress,
        routed=routed,
        route=route,
        skip=skip,
        split_min_s=split_min_s,
    )
