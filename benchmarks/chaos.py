"""Faults a building's server room has, against a fleet: ``fleet_sim.py``'s robots (its ``robot``
threads, unchanged) and a writer of steady changes (robot ``chaos-writer``: a probe table added every
0.5 s, removed by the next step) report to a daemon behind a ``twin router`` on the lab, recording to
Rerun, while this script injects, round-robin every ``--every`` seconds:

- ``kill9``: kill -9 of the daemon, restarted at once by the script on the same store;
- ``router``: the router killed and started again on its endpoint;
- ``disk_full``: the store's file system (a tmpfs of its own, mounted by this script: run as root) filled
  to the last byte for ``--disk-window`` seconds, then freed;
- ``recorder``: the daemon's Rerun writer child killed with SIGKILL.

Per fault it prints: acked observations lost (after a kill, the daemon's revision must not fall below
the highest revision acked before; at the end every element an ack names as upserted must be in the
store, and every element an ack of the writer names as removed must be removed: see :class:`Writer`),
the seconds until a map was served again through the router (``disk_full``: until writes
were acked again after the window; ``recorder``: until a new writer ran), the robots' errors during
the fault's slot, and the store's state that ``twin status`` showed. At the end: duplicates and ghosts
against the ground truth (``fleet_sim.sample``).

    sudo nice -n 10 python benchmarks/chaos.py --duration 600 --robots 4 --objects 10 --json chaos.json

Exit code 1 when an acked observation was lost.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fleet_sim  # benchmarks/ is not a package
import live

ROOT = live.ROOT
FAULTS = ("kill9", "router", "disk_full", "recorder")
STOREY, SKILL = "ground-floor", "lab-navigation"


@dataclass
class Ack:
    robot: str
    at: float
    revision: int | None
    upserted: list[str]
    removed: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, robot: str, ack: dict[str, Any]) -> Ack:
        return cls(
            robot,
            time.time(),
            ack.get("revision"),
            list(ack.get("upserted", [])),
            list(ack.get("removed", [])),
        )


@dataclass
class Fault:
    kind: str
    at: float
    recovered_s: float | None = None
    errors: int = 0
    lost: int = 0
    store_states: set[str] = field(default_factory=set)
    note: str = ""


@dataclass
class Writer:
    """A steady stream of acked changes (robot ``chaos-writer``): probe tables added at free spots away
    from the objects, each removed by the next step. Every element an acked add names as upserted must
    be in the store at the end, and every element an acked removal names as removed must be removed.

    The writer counts what the acks name, not what it sent: a probe minted where the twin already holds
    a table of its size (another probe whose removal was refused during a fault, or a fleet robot's
    false detection not yet removed by absence) resolves to that element (association: the ack says
    ``"resolved"``, nothing is created, the probe's IRI becomes an alias), and its removal then removes
    that element, through the alias (the ack says which). The probe's own IRI is then never
    ``twin:removed``: counting it as a lost removal was the one "acked change lost" of a 10-minute run.
    """

    added: list[str] = field(default_factory=list)
    """Probes whose add was acked (created, or resolved to an element the twin held)."""
    removed: list[tuple[str, float]] = field(default_factory=list)
    """Elements acked as removed by the writer's removals, with when."""
    resolved: dict[str, str] = field(default_factory=dict)
    """Probe -> the element the twin held that its add resolved to."""
    removals: int = 0
    current: str | None = None
    """The probe the next step removes (None: the next step adds one)."""
    errors: int = 0
    refusals: list[str] = field(default_factory=list)

    def noted(self, iri: str, ack: dict[str, Any]) -> None:
        """Note the ack of adding (no :attr:`current`) or removing probe ``iri``."""
        if self.current is None:
            self.added.append(iri)
            target = dict(ack.get("resolved", {})).get(iri)
            if target is not None:
                self.resolved[iri] = str(target)
            self.current = iri
            return
        self.removals += 1
        self.removed += [(str(e), time.time()) for e in ack.get("removed", [])]
        self.current = None


def write_changes(  # noqa: PLR0917 (a thread's target)
    endpoint: str,
    prefix: str,
    world: fleet_sim.World,
    acks: list[Ack],
    lock: threading.Lock,
    writer: Writer,
    stop: threading.Event,
) -> None:
    from adapters.zenoh.client import TwinClient

    rng = random.Random(7)
    n = 0
    with TwinClient.connect([endpoint], prefix=prefix, mode="client", timeout_s=10.0) as twin:
        while not stop.wait(0.5):
            if writer.current is None:
                while True:
                    x, y = world.random_free(rng)
                    if all(math.dist((x, y), (o.x, o.y)) > 1.5 for o in world.objects.values()):
                        break
                n += 1
                iri = f"urn:chaos:probe-{n}"
                turtle = (
                    f'{fleet_sim.PREFIX}<{iri}> twin:ifcClass "IfcFurniture" ; twin:storey "{STOREY}" ; '
                    f'twin:box "{x:.3f} {y:.3f} 0.3 0.5 0.5 0.6 0" .'
                )
            else:
                iri = writer.current
                turtle = f"{fleet_sim.PREFIX}<{iri}> twin:removed true ."
            try:
                ack = twin.observe("chaos-writer", turtle)
            except Exception as err:
                writer.errors += 1
                writer.refusals.append(str(err)[:200])
                writer.current = None  # a refused removal (say, fusion removed the probe first): a new one
                continue
            with lock:
                acks.append(Ack.of("chaos-writer", ack))
            writer.noted(iri, ack)


def recording_client(acks: list[Ack], lock: threading.Lock) -> type:
    """A TwinClient that remembers every ack (the robots import the class when they start)."""
    from adapters.zenoh.client import TwinClient

    class RecordingClient(TwinClient):
        def observe(self, robot: str, turtle: bytes | str) -> dict[str, Any]:
            ack = super().observe(robot, turtle)
            if not ack.get("unchanged"):
                with lock:
                    acks.append(Ack.of(robot, ack))
            return ack

    return RecordingClient


class Processes:
    """The router and the daemon as processes with their output in files."""

    def __init__(self, work: Path, store: Path, config: Path, endpoint: str) -> None:
        self.work, self.store, self.config, self.endpoint = work, store, config, endpoint
        self.router: subprocess.Popen[bytes] | None = None
        self.daemon: subprocess.Popen[bytes] | None = None
        self.starts = 0

    def _start(self, name: str, args: list[str], ready: str) -> subprocess.Popen[bytes]:
        log = self.work / f"{name}-{self.starts}.log"
        self.starts += 1
        with log.open("wb") as out:
            p = subprocess.Popen(
                live._twin(*args), stdout=out, stderr=subprocess.STDOUT, cwd=ROOT,
                env={**os.environ, "PYTHONUNBUFFERED": "1"},
            )  # fmt: skip
        deadline = time.monotonic() + 120
        while ready not in log.read_text(errors="replace"):
            if p.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"{name} did not start:\n{log.read_text(errors='replace')[-2000:]}")
            time.sleep(0.05)
        return p

    def start_router(self) -> None:
        self.router = self._start("router", ["router", "--listen", self.endpoint], "router ")

    def start_daemon(self) -> None:
        args = ["--config", str(self.config), "serve", "--store", str(self.store), "--mode", "client"]
        args += ["--connect", self.endpoint, "--record", str(self.work / "run.rrd")]
        self.daemon = self._start("daemon", args, "serving site")

    def recorders(self) -> list[int]:
        assert self.daemon is not None
        pids: list[str] = []
        with contextlib.suppress(OSError):
            for task in Path(f"/proc/{self.daemon.pid}/task").iterdir():
                with contextlib.suppress(OSError):
                    pids += (task / "children").read_text().split()
        out = []
        for pid in pids:
            with contextlib.suppress(OSError):
                if b"adapters.rerun.child" in Path(f"/proc/{pid}/cmdline").read_bytes():
                    out.append(int(pid))
        return out

    def stop(self) -> int | None:
        code = None
        for p in (self.daemon, self.router):
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            if p is self.daemon and p is not None:
                code = p.returncode
        return code


def fill(disk: Path) -> Path:
    """Fill ``disk``'s file system to the last byte; return the filler file."""
    filler = disk / "filler"
    chunk = b"\0" * (1 << 20)
    with filler.open("wb", buffering=0) as f:
        with contextlib.suppress(OSError):
            while True:
                f.write(chunk)
        with contextlib.suppress(OSError):
            while True:
                f.write(b"\0" * 4096)
    return filler


def world_of(oracle: Any, args: argparse.Namespace) -> fleet_sim.World:
    """``fleet_sim``'s world on the lab's ground floor with ``args.objects`` objects, applied to the
    oracle (as ``fleet_sim.run`` sets it up)."""
    from twin.maps.grid import OCCUPIED

    m = oracle.live_maps.skill_maps[(STOREY, SKILL)]
    f = m.plan.frame
    blocked = m.data == OCCUPIED
    free = m.data == 0
    for _ in range(math.ceil(0.35 / f.resolution_m)):
        grown = free.copy()
        grown[1:, :] &= free[:-1, :]
        grown[:-1, :] &= free[1:, :]
        grown[:, 1:] &= free[:, :-1]
        grown[:, :-1] &= free[:, 1:]
        free = grown
    elevation = oracle.live.site.storeys[STOREY].elevation_m
    world = fleet_sim.World(free, blocked, (f.origin_x, f.origin_y), f.resolution_m, elevation)
    rng = random.Random(args.seed)
    for k in range(args.objects):
        spot = world.place(rng)
        if spot is None:
            break
        o = fleet_sim.Obj(k, *spot, rng.uniform(0.5, 0.9), rng.uniform(0.35, 0.6), rng.uniform(0.5, 0.9))
        world.objects[k] = o
        fleet_sim.apply_truth(oracle, fleet_sim.truth_box(o, STOREY, elevation))
    return world


def probe_maps(endpoint: str, prefix: str, since: float, timeout_s: float = 120.0) -> float | None:
    """Seconds from ``since`` until a map is served through the router (a fresh client each try)."""
    from adapters.zenoh.client import TwinClient

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with TwinClient.connect([endpoint], prefix=prefix, mode="client", timeout_s=3.0) as c:
                grid, _, _ = c.get_map(STOREY, SKILL)
                if grid.data.size:
                    return time.time() - since
        except Exception:  # not yet
            time.sleep(0.2)
    return None


def store_state(endpoint: str, prefix: str) -> str:
    from adapters.zenoh.client import TwinClient

    try:
        with TwinClient.connect([endpoint], prefix=prefix, mode="client", timeout_s=3.0) as c:
            return str(c.status().get("store", "?"))
    except Exception as err:
        return f"no answer ({type(err).__name__})"


def status_revision(endpoint: str, prefix: str) -> int | None:
    from adapters.zenoh.client import TwinClient

    for _ in range(50):
        try:
            with TwinClient.connect([endpoint], prefix=prefix, mode="client", timeout_s=3.0) as c:
                return int(c.status()["revision"])
        except Exception:
            time.sleep(0.2)
    return None


def inject(
    kind: str,
    procs: Processes,
    *,
    disk: Path,
    args: argparse.Namespace,
    acks: list[Ack],
    lock: threading.Lock,
    prefix: str,
) -> Fault:
    ep = procs.endpoint
    fault = Fault(kind, time.time())
    if kind == "kill9":
        with lock:
            acked_max = max((a.revision or 0 for a in acks), default=0)
        assert procs.daemon is not None
        procs.daemon.kill()
        procs.daemon.wait()
        with lock:  # an ack may have left between the read and the kill
            acked_max = max((a.revision or 0 for a in acks), default=acked_max)
        fault.at = time.time()
        procs.start_daemon()
        fault.recovered_s = probe_maps(ep, prefix, fault.at)
        revision = status_revision(ep, prefix)
        fault.lost = max(0, acked_max - (revision or 0))
        fault.note = f"acked revision {acked_max}, after the restart {revision}"
    elif kind == "router":
        assert procs.router is not None
        procs.router.kill()
        procs.router.wait()
        time.sleep(2.0)  # an outage, not a blink
        procs.start_router()
        restarted = time.time()
        fault.recovered_s = probe_maps(ep, prefix, restarted)
        fault.note = f"recovered_s: from the router's restart ({restarted - fault.at:.1f} s after the kill)"
    elif kind == "disk_full":
        filler = fill(disk)
        end = time.time() + args.disk_window
        while time.time() < end:
            fault.store_states.add(store_state(ep, prefix))
            time.sleep(2.0)
        filler.unlink()
        freed = time.time()
        with lock:
            n = len(acks)
            during = [a for a in acks if a.robot == "chaos-writer" and fault.at + 1 < a.at < freed]
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            with lock:
                later = [a for a in acks[n:] if a.robot == "chaos-writer"]
            if later:
                fault.recovered_s = later[0].at - freed
                break
            time.sleep(0.1)
        fault.store_states.add(store_state(ep, prefix))
        fault.note = (
            f"recovered_s: from the space coming back to the writer's next ack; "
            f"{len(during)} changes acked while full"
        )
    elif kind == "recorder":
        old = procs.recorders()
        for pid in old:
            os.kill(pid, signal.SIGKILL)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if [p for p in procs.recorders() if p not in old]:
                fault.recovered_s = time.time() - fault.at
                break
            time.sleep(0.1)
        fault.note = f"killed writer(s) {old}; recovered_s: until a new writer ran"
    return fault


def _row(f: Fault, t0: float) -> dict[str, Any]:
    return {**f.__dict__, "store_states": sorted(f.store_states), "t": round(f.at - t0, 1)}


Sparql = Callable[[str], dict[str, Any]]
"""A SELECT in, its SPARQL JSON results out (``TwinClient.sparql``)."""


def lost_upserts(sparql: Sparql, acks: list[Ack]) -> list[str]:
    """Elements acked as upserted that the store does not hold (as subject or object)."""
    iris = sorted({i for a in acks for i in a.upserted})
    missing: list[str] = []
    for k in range(0, len(iris), 200):
        part = iris[k : k + 200]
        values = " ".join(f"<{i}>" for i in part)
        rows = sparql(
            f"SELECT DISTINCT ?e WHERE {{ VALUES ?e {{ {values} }} {{ ?e ?p ?o }} UNION {{ ?s ?q ?e }} }}"
        )["results"]["bindings"]
        found = {r["e"]["value"] for r in rows}
        missing += [i for i in part if i not in found]
    return missing


def lost_removals(sparql: Sparql, removed: list[tuple[str, float]], acks: list[Ack]) -> list[str]:
    """Elements acked as removed (``removed``: IRI and when) that the store does not show removed,
    unless an ack after the removal upserted them again."""
    again = {i: a.at for a in acks for i in a.upserted}
    iris = sorted({i for i, at in removed if again.get(i, 0.0) <= at})
    missing: list[str] = []
    for k in range(0, len(iris), 200):
        part = iris[k : k + 200]
        values = " ".join(f"<{i}>" for i in part)
        rows = sparql(f"SELECT DISTINCT ?e WHERE {{ VALUES ?e {{ {values} }} ?e twin:removed true }}")
        found = {r["e"]["value"] for r in rows["results"]["bindings"]}
        missing += [i for i in part if i not in found]
    return missing


def what_the_store_holds(sparql: Sparql, iri: str) -> list[dict[str, Any]]:
    """Every triple naming ``iri`` (as subject or object), at most 10."""
    rows: list[dict[str, Any]] = sparql(
        f"SELECT ?s ?p ?o WHERE {{ {{ <{iri}> ?p ?o BIND(<{iri}> AS ?s) }} UNION "
        f"{{ ?s ?p <{iri}> BIND(<{iri}> AS ?o) }} }} LIMIT 10"
    )["results"]["bindings"]
    return rows


def run(args: argparse.Namespace) -> dict[str, Any]:
    import adapters.zenoh.client as client_module

    work = Path(tempfile.mkdtemp(prefix="chaos-"))
    disk = work / "disk"
    disk.mkdir()
    built = live.prepare_store("lab", work)
    size_mb = sum(p.stat().st_size for p in built.rglob("*") if p.is_file()) / 2**20
    size = f"size={int(size_mb + args.headroom_mb)}m"
    subprocess.run(["mount", "-t", "tmpfs", "-o", size, "tmpfs", str(disk)], check=True)
    procs: Processes | None = None
    stop = threading.Event()
    keep = threading.Event()  # set when something was lost: the logs stay in ``work``
    threads: list[threading.Thread] = []
    oracle = None
    try:
        store = disk / "store"
        shutil.copytree(built, store)
        oracle = fleet_sim.oracle_service(built, work)
        world = world_of(oracle, args)
        config = work / "chaos.toml"
        config.write_text(f"[fusion]\ntentative_sightings = {args.tentative}\n")
        endpoint = f"tcp/127.0.0.1:{live._free_port()}"
        procs = Processes(work, store, config, endpoint)
        procs.start_router()
        procs.start_daemon()
        prefix = "twin/lab"
        acks: list[Ack] = []
        lock = threading.Lock()
        original = client_module.TwinClient
        client_module.TwinClient = recording_client(acks, lock)  # type: ignore[misc]
        stats = [fleet_sim.RobotStats() for _ in range(args.robots)]
        t0 = time.time()
        t_end = t0 + args.duration
        try:
            for i in range(args.robots):
                t = threading.Thread(
                    target=fleet_sim.robot,
                    args=(i, endpoint, prefix, world, STOREY, args, t_end, t_end, stats[i], stop),
                    daemon=True,
                )
                t.start()
                threads.append(t)
            writer = Writer()
            w = threading.Thread(
                target=write_changes,
                args=(endpoint, prefix, world, acks, lock, writer, stop),
                daemon=True,
            )
            w.start()
            threads.append(w)
            time.sleep(2.0)
        finally:
            client_module.TwinClient = original  # type: ignore[misc]
        faults: list[Fault] = []
        k = 0
        next_at = t0 + args.every
        while next_at < t_end - args.every / 2:
            time.sleep(max(0.0, next_at - time.time()))
            errors0 = sum(s.errors for s in stats) + writer.errors
            fault = inject(
                FAULTS[k % len(FAULTS)], procs, disk=disk, args=args, acks=acks, lock=lock, prefix=prefix
            )
            k += 1
            next_at = max(next_at + args.every, time.time() + 5)
            time.sleep(max(0.0, min(next_at, t_end) - time.time() - 0.5))
            fault.errors = sum(s.errors for s in stats) + writer.errors - errors0
            faults.append(fault)
            print(json.dumps(_row(fault, t0)), flush=True)
        time.sleep(max(0.0, t_end - time.time()))
        stop.set()
        for t in threads:
            t.join(timeout=60)
        from adapters.zenoh.client import TwinClient

        time.sleep(1.0)
        with TwinClient.connect([endpoint], prefix=prefix, mode="client", timeout_s=30.0) as c:
            if writer.current is not None:  # the last probe: not a ghost of the fleet's
                with contextlib.suppress(Exception):
                    c.observe("chaos-writer", f"{fleet_sim.PREFIX}<{writer.current}> twin:removed true .")
            final = fleet_sim.sample(c, world, STOREY, oracle, SKILL, t0, {})
            end_revision = int(c.status()["revision"])
        with TwinClient.connect([endpoint], prefix=prefix, mode="client", timeout_s=30.0) as c:
            missing_upserts = lost_upserts(c.sparql, acks)
            missing_removals = lost_removals(c.sparql, writer.removed, acks)
            missing = missing_upserts + missing_removals
            missing_detail = []
            for iri in missing[:5]:  # what the store says of it, and when it was acked
                when = [
                    (round(a.at - t0, 2), a.revision, a.robot, "upserted" if iri in a.upserted else "removed")
                    for a in acks
                    if iri in a.upserted or iri in a.removed
                ]
                missing_detail.append(
                    {"iri": iri, "acked": when, "triples": what_the_store_holds(c.sparql, iri)}
                )
        if missing:
            keep.set()
        exit_code = procs.stop()
        procs = None
        return {
            "duration_s": args.duration,
            "robots": args.robots,
            "objects": len(world.objects),
            "faults": [_row(f, t0) for f in faults],
            "acked_changes": len(acks),
            "acked_observations": sum(s.acked for s in stats),
            "sent": sum(s.sent for s in stats),
            "robot_errors": sum(s.errors for s in stats),
            "writer_changes_acked": len(writer.added) + writer.removals,
            "writer_adds_resolved": len(writer.resolved),
            "writer_resolved_sample": dict(list(writer.resolved.items())[:5]),
            "writer_errors": writer.errors,
            "writer_refusals_sample": sorted(set(r[:120] for r in writer.refusals))[:6],
            "acked_upserts_missing": missing_upserts[:20],
            "acked_removals_missing": missing_removals[:20],
            "missing_detail": missing_detail,
            "work": str(work) if missing else None,
            "acked_lost": len(missing) + sum(f.lost for f in faults),
            "end_revision": end_revision,
            "duplicates": final["duplicates"],
            "ghosts": final["ghosts"],
            "ghost_iris": final["ghost_iris"][:10],
            "viewed_ghosts": final["viewed_ghosts"],
            "missing_objects": final["missing"],
            "daemon_exit_code": exit_code,
        }
    finally:
        stop.set()
        if procs is not None:
            procs.stop()
        if oracle is not None:
            oracle.store.close()
        subprocess.run(["umount", "-l", str(disk)], check=False)
        if not keep.is_set():
            shutil.rmtree(work, ignore_errors=True)


def main() -> int:
    p = fleet_sim.parser()
    p.description = (__doc__ or "").split("\n\n")[0]
    p.set_defaults(duration=600.0, robots=4, objects=10)
    p.add_argument("--every", type=float, default=45.0, help="seconds between faults")
    p.add_argument("--disk-window", type=float, default=20.0)
    p.add_argument("--headroom-mb", type=float, default=96.0, help="free space of the store's tmpfs")
    args = p.parse_args()
    if os.geteuid() != 0:
        print("chaos.py: the store's tmpfs is mounted by this script: run it as root", file=sys.stderr)
        return 2
    result = run(args)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    print(f"{'fault':10} {'t_s':>6} {'lost':>4} {'recovered_s':>11} {'errors':>6}  store")
    for f in result["faults"]:
        rec = "-" if f["recovered_s"] is None else f"{f['recovered_s']:.1f}"
        states = "; ".join(f["store_states"])
        print(f"{f['kind']:10} {f['t']:6.0f} {f['lost']:4} {rec:>11} {f['errors']:6}  {states}")
    for k, v in result.items():
        if k != "faults":
            print(f"{k:24} {v}")
    return 1 if result["acked_lost"] else 0


if __name__ == "__main__":
    sys.exit(main())
