"""``twin demo``: the live loop on the bundled lab, end to end, as separate processes on loopback.

Generates the lab, imports it, starts the daemon, starts a watcher (a robot subscribed to the
lab-navigation map of the ground floor), lets a robot observe a table in the corridor and then open
the door, prints every map version the watcher receives, stops the daemon cleanly and writes every
skill map. Everything lands in ``--workdir`` (default ``var/``).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import IO, Any

from adapters.cli.common import key_prefix
from twin.config import Config

# The table the robot sees: in the corridor, east of the arch (lab frame + the building's offset).
TABLE_BOX = "16.6,7.0,0.375,0.6,0.6,0.75,0.3"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _twin(*args: str) -> list[str]:
    return [sys.executable, "-m", "adapters.cli", *args]


def _step(text: str) -> None:
    print(f"\n== {text}", flush=True)


def _run(*args: str) -> str:
    done = subprocess.run(_twin(*args), capture_output=True, text=True, check=False, timeout=300)
    if done.returncode != 0:
        msg = f"'twin {' '.join(args)}' failed: {done.stderr.strip()}"
        raise RuntimeError(msg)
    return done.stdout


def _wait_line(stream: IO[str], needle: str, timeout_s: float) -> str:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = stream.readline()
        if not line:
            break
        print(f"   daemon | {line.rstrip()}", flush=True)
        if needle in line:
            return line
    msg = f"the daemon did not say {needle!r} within {timeout_s} s"
    raise RuntimeError(msg)


def cmd_demo(args: argparse.Namespace, cfg: Config) -> int:
    from adapters.cli.robot_cmds import box_turtle
    from adapters.zenoh.client import TwinClient

    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    ifc, store, maps = work / "lab.ifc", work / "store", work / "maps"
    recording = work / "recordings" / "demo.rrd"
    endpoint = f"tcp/127.0.0.1:{args.port or _free_port()}"
    t0 = time.perf_counter()

    _step("generate the bundled lab (2 storeys) and import it")
    print(_run("sample", "lab", str(ifc), "--storeys", "2").strip())
    print(_run("import", str(ifc), "--store", str(store), "--replace").strip())

    _step(f"start the daemon on {endpoint}")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    daemon = subprocess.Popen(
        _twin("serve", "--store", str(store), "--listen", endpoint, "--record", str(recording)),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    watcher: subprocess.Popen[str] | None = None
    try:
        assert daemon.stdout is not None
        _wait_line(daemon.stdout, "serving site", 120)

        _step("a robot subscribes to the lab-navigation map of the ground floor")
        watcher = subprocess.Popen(
            _twin(
                "watch",
                "--connect",
                endpoint,
                "--skill",
                "lab-navigation",
                "--storey",
                "ground-floor",
                "--count",
                "3",
                "--out",
                str(maps / "watched"),
                "--for",  # the whole watch: it ends even if a version never came
                "60",
            ),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        assert watcher.stdout is not None
        print(f"   watch  | {watcher.stdout.readline().rstrip()}", flush=True)

        with TwinClient.connect([endpoint], prefix=key_prefix(cfg)) as twin:
            _step("robot1 observes a table in the corridor (acked)")
            table = "urn:twin:robot1:table-1"
            box = [float(v) for v in TABLE_BOX.split(",")]
            turtle = box_turtle(table, box, ifc_class="IfcFurniture", storey="ground-floor", label="table")
            ack = twin.observe("robot1", turtle)
            print("   ack    | " + json.dumps(ack))
            rows: Any = twin.sparql('SELECT ?door WHERE { ?door twin:ifcClass "IfcDoor" } LIMIT 1')
            door = rows["results"]["bindings"][0]["door"]["value"]
            _step(f"robot1 finds the door open: {door}")
            print(
                "   ack    | "
                + json.dumps(
                    twin.observe("robot1", f"<{door}> <https://w3id.org/building-twin#isOpen> true .")
                )
            )
            status = twin.status()
        for line in watcher.stdout:
            print(f"   watch  | {line.rstrip()}", flush=True)
        watcher.wait(timeout=60)
        print(
            f"   status | revision {status['revision']}, {len(status['maps'])} maps, "
            f"observations {status['observations']}"
        )
    finally:
        if watcher is not None and watcher.poll() is None:
            watcher.kill()
        _step("stop the daemon (SIGINT)")
        daemon.send_signal(signal.SIGINT)
        try:
            out, _ = daemon.communicate(timeout=20)
            for line in out.splitlines():
                print(f"   daemon | {line}", flush=True)
        except subprocess.TimeoutExpired:
            daemon.kill()
            raise
    if daemon.returncode != 0:
        print(f"twin: error: the daemon exited with {daemon.returncode}", file=sys.stderr)
        return 1

    _step("write every skill map of the twin as it is now")
    print(_run("map", "--store", str(store), "--all-skills", "--out", str(maps)).strip())
    print(
        f"\ndone in {time.perf_counter() - t0:.1f} s. Maps (nav2 map_server YAML+PGM, PNG, CDR): {maps}/"
        f"\n  the watcher's copy of the live map: {maps / 'watched'}/"
        + (f"\n  Rerun recording: {recording} (replay with: rerun {recording})" if recording.exists() else "")
    )
    return 0


def add_parser(sub: Any) -> None:
    sp = sub.add_parser("demo", help="the live loop on the bundled lab: daemon, robot, watcher (loopback)")
    sp.add_argument(
        "--workdir", default="var", help="where the lab, store, maps and recording go (default: var)"
    )
    sp.add_argument("--port", type=int, help="TCP port on 127.0.0.1 for the daemon (default: a free one)")
    sp.set_defaults(func=cmd_demo)
