"""New route graph versions while ``twin serve`` runs: a structural change rebuilds the graphs it touches.

:class:`RouteUpdates` is a sink of the twin service (:mod:`twin.live.events`). On the writer's thread it
only notes which routes skills a change touches:

- an accepted observation that upserted a static element (or removed one the twin held as static) and
  changed the navigation map of a storey a routes skill serves (its ``maps``); a routes skill that
  made no graph at start is tried again on such a change of a storey it names (any, if it names none);
- a skill change of a routes skill's navigation skill or of one of its keepout skills.

Dynamic changes (furniture, a door opened) never rebuild a graph. A thread of its own waits until no
change came for ``debounce_s``, then rebuilds each touched skill's graph from the store (a fresh scene:
robots' structural elements included) and, when the graph differs from the one served, publishes it as
the next version (:class:`adapters.zenoh.routes.ZenohRoutes`, ``"version"`` in the JSON), puts a new
Open-RMF ``BuildingMap`` on ``/map`` and sends ``on_graph`` a
:class:`~twin.live.events.RoutesPublished` (the Rerun recorder's ``emit``). :meth:`close`
stops the thread and joins it (``twin serve``'s stop).

Example::

    updates = RouteUpdates(served, cfg, store, skills=lambda: service.skills, debounce_s=1.0)
    service.sinks.append(updates)
    ...
    updates.close()
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Callable, Iterable, Mapping

from adapters.cli.map_routes import ServedRoutes, route_graph
from twin.config import Config
from twin.errors import TwinError
from twin.graph.store import GraphStore
from twin.live.events import ObservationAccepted, RoutesPublished, SkillChanged, TwinEvent, TwinStarted
from twin.maps.scene import load_scene
from twin.routes.graph import RouteGraph
from twin.selection.skills import SkillProfile

log = logging.getLogger(__name__)

DEBOUNCE_S = 1.0
"""How long the twin must be quiet after a structural change before the graphs are rebuilt."""


def routes_published(cfg: Config, graph: RouteGraph, version: int) -> RoutesPublished:
    """The event that tells the recorder of ``graph``'s ``version``."""
    return RoutesPublished(graph, cfg.routes[graph.skill].navigation, version, time.time_ns())


class RouteUpdates:
    """The sink that turns structural changes into new route graph versions (see the module)."""

    def __init__(
        self,
        served: ServedRoutes,
        cfg: Config,
        store: GraphStore,
        *,
        skills: Callable[[], Mapping[str, SkillProfile]],
        debounce_s: float = DEBOUNCE_S,
        on_graph: Callable[[RoutesPublished], None] | None = None,
        static: Iterable[str] = (),
    ) -> None:
        """``skills``: the service's current map skills (read on the rebuild thread). ``static``: the
        IRIs of the twin's static elements when the sink joins after the service started."""
        self.served = served
        self.cfg = cfg
        self.store = store
        self.skills = skills
        self.debounce_s = debounce_s
        self.on_graph = on_graph
        self.rebuilds = 0
        """Graphs rebuilt (changed or not): for tests and the log."""
        self._static: set[str] = set(static)
        self._dirty: set[str] = set()
        self._last_change = 0.0
        self._closed = False
        self._wake = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="twin-route-updates", daemon=True)
        self._thread.start()

    # --- the sink (writer's thread: notes, never builds) ---------------------------------------------
    def emit(self, event: TwinEvent) -> None:
        touched: set[str] = set()
        if isinstance(event, TwinStarted):
            self._static = {e.iri for e in event.elements if e.is_static}
        elif isinstance(event, ObservationAccepted):
            static = [e.iri for e in event.upserted if e.is_static]
            structural = bool(static) or any(iri in self._static for iri in event.removed)
            self._static.update(static)
            self._static.difference_update(event.removed)
            self._static.difference_update(e.iri for e in event.upserted if not e.is_static)
            if structural:
                changed = {(m.storey, m.skill) for m in event.maps if not m.window.empty}
                touched = {name for name in self.cfg.routes if self._follows(name, changed)}
        elif isinstance(event, SkillChanged):
            touched = {
                name
                for name, routes in self.cfg.routes.items()
                if event.name in (routes.navigation, *routes.keepout)
            }
        if touched:
            with self._wake:
                self._dirty |= touched
                self._last_change = time.monotonic()
                self._wake.notify()

    def _follows(self, name: str, changed: set[tuple[str, str]]) -> bool:
        """Whether the routes skill ``name``'s graph follows one of the ``changed`` (storey, skill) maps:
        its navigation skill's map of a storey it serves (a skill not served yet: of a storey it names,
        or of any when it names none)."""
        routes = self.cfg.routes[name]
        graph = self.served.graphs.get(name)
        storeys = {s.storey for s in graph.storeys} if graph is not None else set(routes.storeys)
        return any(
            skill == routes.navigation and (storey in storeys or (graph is None and not storeys))
            for storey, skill in changed
        )

    # --- the rebuild thread --------------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            with self._wake:
                while not self._closed and not self._dirty:
                    self._wake.wait()
                while not self._closed and (quiet := time.monotonic() - self._last_change) < self.debounce_s:
                    self._wake.wait(self.debounce_s - quiet)
                if self._closed:
                    return
                names, self._dirty = sorted(self._dirty), set()
            try:
                self._rebuild(names)
            except Exception:  # a bug costs one rebuild, never the daemon
                log.exception("Internal error while rebuilding the route graphs %s", ", ".join(names))

    def _rebuild(self, names: list[str]) -> None:
        cfg = dataclasses.replace(self.cfg, skills={**self.cfg.skills, **self.skills()})
        scene = load_scene(self.store)
        for name in names:
            t0 = time.perf_counter()
            try:
                graph = route_graph(cfg, self.store, scene, name)
            except TwinError as err:
                log.error("Routes skill %s: the changed building makes no graph (%s); last kept", name, err)
                continue
            self.rebuilds += 1
            version = self.served.update(graph, cfg, self.store, scene)
            if version is None:
                log.info("Routes skill %s: unchanged by the structural change", name)
                continue
            log.info(
                "Routes skill %s: version %d after a structural change (%.2f s)",
                name,
                version,
                time.perf_counter() - t0,
            )
            if self.on_graph is not None:
                self.on_graph(routes_published(self.cfg, graph, version))

    def close(self) -> None:
        """Stop the rebuild thread (a rebuild under way finishes first) and join it."""
        with self._wake:
            self._closed = True
            self._wake.notify()
        self._thread.join()
