"""The robot side: a small client of the daemon over Zenoh (what ``twin observe`` and ``twin watch`` use).

Example::

    with TwinClient.connect(["tcp/127.0.0.1:7447"], prefix="twin/lab") as twin:
        ack = twin.observe("robot1", turtle)              # {"ok": true, "revision": ..., "maps": [...]}
        grid, revision, version = twin.get_map("ground-floor", "navigation")
        xyz, revision, version = twin.get_points("ground-floor", "lidar3d")   # a points skill's cloud
        with twin.watch("ground-floor", "navigation", on_version=print) as watcher:
            ...
        graph = twin.sparql("CONSTRUCT { ?s ?p ?o } WHERE { ?s a bot:Storey ; ?p ?o }")  # rdflib.Graph
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any, Self

import zenoh

from adapters.zenoh.errors import DaemonTimeoutError, RemoteError, TransportError
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.latched import LatchedSubscription
from adapters.zenoh.probe import explain_unreachable, probe
from adapters.zenoh.session import client_config
from adapters.zenoh.settings import ZenohMode, ZenohSettings

if TYPE_CHECKING:  # the decoders (NumPy) and rdflib are imported by what uses them: 'twin observe' does not
    import numpy as np
    import numpy.typing as npt
    import rdflib

    from twin.maps.grid import OccupancyGrid

log = logging.getLogger(__name__)

MIN_QUERY_S = 0.5
"""A query found its daemon: it gets at least this long to answer, even at the end of the timeout."""


def _meta(sample: zenoh.Sample) -> tuple[int, int]:
    """``(revision, version)`` from a map sample's attachment."""
    if sample.attachment is None:
        return (-1, -1)
    try:
        data = json.loads(sample.attachment.to_bytes())
        return int(data["revision"]), int(data["version"])
    except (ValueError, KeyError, TypeError):
        return (-1, -1)


def _error_text(payload: bytes) -> str:
    try:
        data = json.loads(payload)
        return str(data.get("error", payload.decode(errors="replace")))
    except (ValueError, AttributeError):
        return payload.decode(errors="replace")


@dataclass(frozen=True, slots=True)
class MapVersion:
    """A robot's copy of a map after a full map or an update: ``via`` is ``"map"`` or ``"update"``."""

    grid: OccupancyGrid
    revision: int
    version: int
    via: str


class MapWatcher:
    """Keeps a copy of one map current: the latched full map, then updates applied in order.

    An update applies when it brings the copy from version V to V+1; after a missed update (a gap) the
    watcher asks for the current map (a ``get``, at most once a second) and goes on from it; the
    daemon's keyframes (at most every ``keyframe_interval_s``) would heal it too.
    """

    def __init__(
        self,
        session: zenoh.Session,
        keys: SiteKeys,
        storey: str,
        skill: str,
        on_version: Callable[[MapVersion], None] | None,
    ) -> None:
        import adapters.ros.cdr  # noqa: PLC0415 F401 (here, not in a callback thread: they import it too)

        self.storey, self.skill = storey, skill
        self.on_version = on_version
        self.latest: MapVersion | None = None
        self.received = 0
        """How many versions the copy went through (only the latest is kept: a watcher runs all day)."""
        self._cond = threading.Condition()
        self._pending: list[tuple[int, int, Any, Any]] = []  # updates that came before their base
        self._ask = lambda: session.get(keys.map(storey, skill), self._on_reply, timeout=10.0)
        self._asked = 0.0  # when the current map was last asked for after a gap (monotonic s)
        self._follow = LatchedSubscription(
            session,
            keys.map(storey, skill),
            keys.map_updates(storey, skill),
            on_map=self._on_map,
            on_update=self._on_update,
        )
        # also ask whoever holds the map now: the daemon, or a router's map storage while it restarts
        session.get(keys.map(storey, skill), self._on_reply, timeout=10.0)

    def _accept(self, version: MapVersion) -> None:
        with self._cond:
            if self.latest is not None and 0 <= version.version <= self.latest.version:
                return  # a full map that the updates already brought the copy to, or an older one
            self.latest = version
            self.received += 1
            self._cond.notify_all()
        if self.on_version is not None:
            try:
                self.on_version(version)
            except Exception:
                log.exception("on_version callback failed")

    def _on_reply(self, reply: zenoh.Reply) -> None:
        if reply.ok is not None:
            self._on_map(reply.ok)

    def _on_map(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:
            return
        revision, version = _meta(sample)
        latest = self.latest
        if latest is not None and 0 <= version <= latest.version:
            return  # an older or repeated full map: the copy is newer
        from adapters.ros.cdr import decode_occupancy_grid  # noqa: PLC0415 (NumPy: a map watcher's)

        grid, _ = decode_occupancy_grid(sample.payload.to_bytes(), storey=self.storey, skill=self.skill)
        self._accept(MapVersion(grid, revision, version, "map"))
        self._drain()

    def _on_update(self, sample: zenoh.Sample) -> None:
        from adapters.ros.cdr import decode_occupancy_grid_update  # noqa: PLC0415 (NumPy: a map watcher's)

        revision, version = _meta(sample)
        window, cells, _ = decode_occupancy_grid_update(sample.payload.to_bytes())
        with self._cond:
            self._pending.append((version, revision, window, cells))
        self._drain()

    def _drain(self) -> None:
        from adapters.ros.cdr import apply_update  # noqa: PLC0415 (NumPy: a map watcher's)

        while True:
            with self._cond:
                base = self.latest
                if base is None:
                    return
                self._pending = [p for p in self._pending if p[0] > base.version]
                nxt = next((p for p in self._pending if p[0] == base.version + 1), None)
                if nxt is None:
                    gap = bool(self._pending) and time.monotonic() - self._asked >= 1.0
                    if gap:
                        self._asked = time.monotonic()
                if nxt is None:
                    if gap:  # an update was missed: ask for the current map
                        self._ask()
                    return
                self._pending.remove(nxt)
            version, revision, window, cells = nxt
            self._accept(MapVersion(apply_update(base.grid, window, cells), revision, version, "update"))

    def wait_for(self, predicate: Callable[[MapVersion], bool], timeout_s: float) -> MapVersion:
        """Block until the copy satisfies ``predicate``; DaemonTimeoutError after ``timeout_s``."""
        with self._cond:
            ok = self._cond.wait_for(lambda: self.latest is not None and predicate(self.latest), timeout_s)
            if not ok or self.latest is None:
                got = "no map" if self.latest is None else f"version {self.latest.version}"
                msg = f"Map {self.storey}/{self.skill}: not there after {timeout_s} s (have {got})."
                raise DaemonTimeoutError(msg)
            return self.latest

    def close(self) -> None:
        self._follow.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


SETTLE_S = 0.25
"""After the first daemon's liveliness token, how long a client looking for the site to talk to waits for
others (a router sends the tokens it knows within milliseconds of each other)."""


def _endpoint_text(endpoints: Sequence[str]) -> str:
    return ", ".join(endpoints) if endpoints else "the configured endpoints"


def daemon_prefixes(
    session: zenoh.Session, template: str, timeout_s: float, *, settle_s: float = SETTLE_S
) -> list[str]:
    """The key prefixes of the daemons alive on ``session``'s network: ``template`` (the configured
    prefix, ``twin/{site}``) with any site, having the liveliness token ``<prefix>/daemon``.

    Listens for the tokens (those present and those declared later) until the first arrives, within
    ``timeout_s``, then ``settle_s`` more for the others; [] when none arrived in time. (A liveliness
    ``get`` sent at once can leave before a router has told a fresh session where the tokens are.)
    """
    pattern = template.replace("{site}", "*").strip("/")
    tokens = SiteKeys(pattern).daemon  # every site's token
    suffix = tokens.removeprefix(pattern)
    found: set[str] = set()
    cond = threading.Condition()

    def on_token(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            with cond:
                found.add(str(sample.key_expr).removesuffix(suffix))
                cond.notify_all()

    subscriber = session.liveliness().declare_subscriber(tokens, on_token, history=True)
    try:
        with cond:
            if cond.wait_for(lambda: bool(found), timeout_s):
                settled = time.monotonic() + settle_s
                while (left := settled - time.monotonic()) > 0:
                    cond.wait(left)  # woken by each further token: wait out the rest
            return sorted(found)
    finally:
        subscriber.undeclare()


def site_of(prefix: str, template: str) -> str:
    """The site name in ``prefix`` (``twin/lab`` -> ``lab`` for the template ``twin/{site}``)."""
    parts, names = prefix.split("/"), template.strip("/").split("/")
    return parts[names.index("{site}")] if "{site}" in names and len(parts) == len(names) else prefix


def _sentence(text: str) -> str:
    return text if text.endswith(("?", ".")) else f"{text}."


def _why_unreachable(endpoints: Sequence[str], settings: ZenohSettings) -> str:
    """The probe's sentence (:mod:`adapters.zenoh.probe`) for a session that reached nobody."""
    tls = settings.tls.certificate is not None or settings.tls.root_ca is not None
    return explain_unreachable(endpoints, credentials=settings.auth.user is not None, tls=tls)


LINK_WAIT_S = 2.0
"""How long a fresh session may take to link to its endpoints before a probe asks why it has not (zenoh
links a peer's endpoints while it opens, so a session that can link has, long before this)."""


def _linked(session: zenoh.Session) -> bool:
    info = session.info
    return any(True for _ in info.peers_zid()) or any(True for _ in info.routers_zid())


def _refused_at_once(session: zenoh.Session, endpoints: Sequence[str], settings: ZenohSettings) -> None:
    """TransportError at once when the session linked to nobody within :data:`LINK_WAIT_S` although an
    endpoint accepts connections: it refused the session, and waiting longer would not change that.
    (Where nothing listens yet, the daemon may still start: the caller waits as before.)"""
    deadline = time.monotonic() + LINK_WAIT_S
    while not _linked(session):
        if time.monotonic() >= deadline:
            if any(probe(e) == "listening" for e in endpoints) and not _linked(session):
                why = _sentence(_why_unreachable(endpoints, settings))
                raise TransportError(f"No session with {', '.join(endpoints)}: {why}")
            return
        time.sleep(0.05)


def _discovered_prefix(
    session: zenoh.Session,
    template: str,
    timeout_s: float,
    endpoints: Sequence[str],
    settings: ZenohSettings | None = None,
) -> str:
    """The prefix of the one daemon alive (see :meth:`TwinClient.connect`)."""
    if "{site}" not in template:
        return template.strip("/")
    _refused_at_once(session, endpoints, settings or ZenohSettings())
    found = daemon_prefixes(session, template, timeout_s)
    if len(found) > 1:
        sites = ", ".join(site_of(p, template) for p in found)
        msg = f"{len(found)} daemons are running, for the sites {sites}: choose one with --site."
        raise TransportError(msg)
    linked = any(True for _ in session.info.peers_zid()) or any(True for _ in session.info.routers_zid())
    if not found and not linked:
        probed = _why_unreachable(endpoints, settings or ZenohSettings())
        where = _endpoint_text(endpoints)
        why = _sentence(probed or "nothing could be reached")
        msg = f"No daemon found at {where} within {timeout_s} s: {why}"
        raise DaemonTimeoutError(msg)
    if not found:
        tokens = SiteKeys(template.replace("{site}", "*").strip("/")).daemon
        msg = (
            f"No daemon found at {_endpoint_text(endpoints)} within {timeout_s} s (no liveliness token "
            f"{tokens}): is 'twin serve' running and reachable there? (Under access control a robot sees "
            "only its own site: give --site.)"
        )
        raise DaemonTimeoutError(msg)
    log.info("talking to the daemon of site %r", site_of(found[0], template))
    return found[0]


def _matching(querier: zenoh.Querier) -> bool:
    """Whether a queryable matching the querier's key expression is known (zenoh 1.10 returns a
    ``MatchingStatus`` here, whose truth value is always true, although its stub says ``bool``)."""
    status: object = querier.matching_status
    return bool(getattr(status, "matching", status))


class TwinClient:
    """Requests to one site's daemon over an open Zenoh session.

    Each request waits, within the client's timeout, until a queryable for its key is known (the
    matching status of a querier on the key) before it is sent: a fresh session learns where the daemon
    is from the peer or router it connects to only after it opened, and a query sent before that finds
    nobody to answer it.
    """

    def __init__(
        self,
        session: zenoh.Session,
        *,
        prefix: str = "twin/lab",
        timeout_s: float = 10.0,
        own: bool = False,
        endpoints: Sequence[str] = (),
        settings: ZenohSettings | None = None,
    ) -> None:
        self.session = session
        self.settings = settings or ZenohSettings()
        self.keys = SiteKeys(prefix.strip("/"))
        self.timeout_s = timeout_s
        self.endpoints = tuple(endpoints)
        self._own = own
        self._queriers: dict[str, zenoh.Querier] = {}
        self._queriers_lock = threading.Lock()

    @classmethod
    def connect(
        cls,
        connect: Sequence[str],
        *,
        prefix: str | None = None,
        timeout_s: float = 10.0,
        settings: ZenohSettings | None = None,
        mode: ZenohMode | None = None,
    ) -> TwinClient:
        """Open a session to ``connect`` (the daemon's or a router's endpoints); close the client after.

        ``mode`` defaults to ``settings.mode`` (``[zenoh] mode``, ``peer`` unless configured). Without
        ``prefix`` (``twin/<site>``), the client talks to the one daemon alive on the network, whatever
        its site (found by its liveliness token ``<prefix>/daemon``, the prefix being ``settings.prefix``
        with any site), waiting up to ``timeout_s`` for one; none is a DaemonTimeoutError naming the
        endpoints, several a TransportError naming their sites.
        """
        if not connect:
            msg = "Give the daemon's endpoint to connect to, e.g. tcp/127.0.0.1:7447."
            raise TransportError(msg)
        settings = settings or ZenohSettings()
        try:
            session = zenoh.open(client_config(connect, settings=settings, mode=mode or settings.mode))
        except TransportError:
            raise
        except Exception as err:
            why = str(err).split("  at /")[0].strip()  # zenoh adds the Rust source location
            probed = _why_unreachable(connect, settings)
            msg = f"Cannot open a Zenoh session to {', '.join(connect)}: {probed or why}"
            raise TransportError(msg) from err
        log.info("zenoh session in %s mode to %s", mode or settings.mode, ", ".join(connect))
        try:
            if prefix is None:
                prefix = _discovered_prefix(session, settings.prefix, timeout_s, connect, settings)
            return cls(
                session, prefix=prefix, timeout_s=timeout_s, own=True, endpoints=connect, settings=settings
            )
        except BaseException:
            session.close()
            raise

    def close(self) -> None:
        with self._queriers_lock:
            queriers = list(self._queriers.values())
            self._queriers.clear()
        if self._own:
            self.session.close()  # undeclares them too
            return
        for querier in queriers:  # a shared session lives on
            try:
                querier.undeclare()
            except Exception as err:  # the session closed first
                log.debug("querier undeclare: %s", err)

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # --- requests ---------------------------------------------------------------------------------
    def _querier(self, key: str) -> zenoh.Querier:
        with self._queriers_lock:
            querier = self._queriers.get(key)
            if querier is None:
                querier = self._queriers[key] = self.session.declare_querier(key)
            return querier

    def wait_for_route(self, key: str, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` until a queryable matching ``key`` is known; False if none is."""
        querier = self._querier(key)
        if _matching(querier):
            return True
        matched = threading.Event()
        listener = querier.declare_matching_listener(lambda s: matched.set() if s.matching else None)
        try:
            return _matching(querier) or matched.wait(timeout_s)
        finally:
            listener.undeclare()

    def _other_sites(self) -> str:
        """What to say when this site's daemon is not there: the sites whose daemons are (a short look)."""
        template = self.settings.prefix
        if "{site}" not in template:
            return "is the daemon of this site running and connected there?"
        found = [site_of(p, template) for p in daemon_prefixes(self.session, template, 1.0, settle_s=0.1)]
        site = site_of(self.keys.prefix, template)
        if not found:
            return f"no daemon of any site answers there: is 'twin serve' for site {site!r} running?"
        return f"no daemon of site {site!r} there; daemons answer for the sites {', '.join(found)}: --site?"

    def connected(self) -> bool:
        """Whether the session is linked to any peer or router."""
        info = self.session.info
        return any(True for _ in info.peers_zid()) or any(True for _ in info.routers_zid())

    def _get(self, selector: str, payload: bytes | None = None, *, what: str) -> list[zenoh.Sample]:
        deadline = time.monotonic() + self.timeout_s
        where = _endpoint_text(self.endpoints)
        if self._own and not self.connected():
            _refused_at_once(self.session, self.endpoints, self.settings)
        if not self.wait_for_route(selector, self.timeout_s):
            if not self.connected():
                probed = _why_unreachable(self.endpoints, self.settings)
                msg = (
                    f"No answer to {what}: nothing could be reached at {where} within {self.timeout_s} s"
                    + (f": {_sentence(probed)}" if probed else ".")
                )
            else:
                msg = (
                    f"No answer to {what}: nothing serves {selector} at {where} within {self.timeout_s} s "
                    f"({self._other_sites()})."
                )
            raise DaemonTimeoutError(msg)
        left = max(deadline - time.monotonic(), MIN_QUERY_S)
        sent = time.monotonic()
        replies = self.session.get(selector, payload=payload, timeout=left)
        samples = []
        for reply in replies:
            if reply.ok is not None:
                samples.append(reply.ok)
            elif reply.err is not None:
                raise RemoteError(_error_text(reply.err.payload.to_bytes()))
        if not samples:
            took = time.monotonic() - sent
            if took < left - MIN_QUERY_S:  # ended early: nobody answered at all
                msg = (
                    f"No answer to {what} at {selector} ({where}): the query ended after {took:.1f} s "
                    "without a reply (refused by access control, or the daemon went away)."
                )
            else:
                msg = f"No answer to {what} at {selector} ({where}) within {self.timeout_s} s."
            raise DaemonTimeoutError(msg)
        return samples

    def observe(self, robot: str, turtle: bytes | str) -> dict[str, Any]:
        """Send an observation and wait for the ack (once durable); RemoteError carries a refusal."""
        payload = turtle.encode() if isinstance(turtle, str) else turtle
        sample = self._get(self.keys.observe(robot), payload, what="the observation")[0]
        ack: dict[str, Any] = json.loads(sample.payload.to_bytes())
        return ack

    def explain(self, storey: str, skill: str, x: float, y: float) -> dict[str, Any]:
        """Why the cell at world ``(x, y)`` of a map is what it is (the daemon's ``explain``)."""
        payload = json.dumps({"storey": storey, "skill": skill, "x": x, "y": y}).encode()
        sample = self._get(self.keys.explain, payload, what="the explanation")[0]
        answer: dict[str, Any] = json.loads(sample.payload.to_bytes())
        return answer

    def publish_observation(self, robot: str, turtle: bytes | str) -> None:
        """Best effort: put the observation, with no ack (errors are only logged by the daemon)."""
        payload = turtle.encode() if isinstance(turtle, str) else turtle
        self.session.put(self.keys.observations(robot), payload)

    def get_map(self, storey: str, skill: str) -> tuple[OccupancyGrid, int, int]:
        """The current map: ``(grid, revision, version)``."""
        from adapters.ros.cdr import decode_occupancy_grid  # noqa: PLC0415 (NumPy: a map watcher's)

        sample = self._get(self.keys.map(storey, skill), what=f"the map {storey}/{skill}")[0]
        grid, _ = decode_occupancy_grid(sample.payload.to_bytes(), storey=storey, skill=skill)
        revision, version = _meta(sample)
        return grid, revision, version

    def get_points(self, storey: str, skill: str) -> tuple[npt.NDArray[np.float32], int, int]:
        """The current cloud of a points skill: ``(xyz, revision, version)``, xyz (n, 3) float32 in the
        map frame."""
        key = self.keys.points_map(storey, skill)
        try:
            sample = self._get(key, what=f"the cloud {storey}/{skill}")[0]
        except DaemonTimeoutError as err:  # a daemon answers nothing for a cloud it does not hold (yet)
            msg = (
                f"{err} A daemon that serves the site answers nothing there until it holds that cloud: "
                f"{skill!r} is not a points skill, {storey!r} not a storey, or the clouds are still being "
                "built after start (subscribe to the key instead: it is latched)."
            )
            raise DaemonTimeoutError(msg) from None
        from adapters.ros.pcd import decode_point_cloud2  # noqa: PLC0415 (NumPy: a map watcher's)

        xyz, _, _ = decode_point_cloud2(sample.payload.to_bytes())
        revision, version = _meta(sample)
        return xyz, revision, version

    def list_maps(self) -> list[tuple[str, str]]:
        """``(storey, skill)`` of every map the daemon serves."""
        found = {self.keys.map_of(str(s.key_expr)) for s in self._get(self.keys.maps, what="the maps")}
        return sorted(m for m in found if m is not None)

    def skills(self) -> dict[str, dict[str, Any]]:
        return {
            self.keys.last(str(s.key_expr)): json.loads(s.payload.to_bytes())
            for s in self._get(self.keys.skills_listing, what="the skills")
        }

    def put_skill(self, name: str, profile: dict[str, Any] | str) -> None:
        text = profile if isinstance(profile, str) else json.dumps(profile)
        self.session.put(self.keys.skill(name), text.encode())

    def delete_skill(self, name: str) -> None:
        self.session.delete(self.keys.skill(name))

    def robot_storey(self, robot: str, storey: str | None = None) -> str:
        """The storey ``robot`` is on; with ``storey``, switch it first (its ROS 2 topics republish that
        storey's maps). RemoteError names an unknown robot or storey (nothing changed then)."""
        payload = storey.encode() if storey is not None else None
        sample = self._get(self.keys.robot_storey(robot), payload, what=f"robot {robot!r}'s storey")[0]
        return sample.payload.to_string()

    def status(self) -> dict[str, Any]:
        data: dict[str, Any] = json.loads(self._get(self.keys.status, what="status")[0].payload.to_bytes())
        return data

    def sparql(self, query: str) -> dict[str, Any] | rdflib.Graph:
        """Run a read-only query: SPARQL JSON results, or an ``rdflib.Graph`` for CONSTRUCT/DESCRIBE."""
        sample = self._get(self.keys.sparql, query.encode(), what="the SPARQL query")[0]
        body = sample.payload.to_bytes()
        if str(sample.encoding).startswith("text/turtle"):
            import rdflib  # noqa: PLC0415 (rarely used, 0.2 s to import)

            graph = rdflib.Graph()
            graph.parse(data=body, format="turtle")
            return graph
        data: dict[str, Any] = json.loads(body)
        return data

    def daemon_alive(self) -> bool:
        """True when the daemon's liveliness token is present."""
        replies = self.session.liveliness().get(self.keys.daemon, timeout=self.timeout_s)
        return any(r.ok is not None for r in replies)

    def watch(
        self, storey: str, skill: str, on_version: Callable[[MapVersion], None] | None = None
    ) -> MapWatcher:
        """Subscribe like a robot: the latched map (late joiners too), then every update."""
        return MapWatcher(self.session, self.keys, storey, skill, on_version)
