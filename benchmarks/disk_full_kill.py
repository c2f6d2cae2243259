"""The store alone against a full disk and ``kill -9``: is every acked write kept?

A child process writes the store as the daemon does (``WatchedStore`` over ``EmbeddedStore``: one
transaction per write, a change of one element and of the model's revision; after a failure the store
reopened and probed every ``--retry`` seconds; the buffers flushed every second) and prints each write
once ``apply`` returned. This script fills the store's file system (a tmpfs of its own: run as root)
and frees it again at random moments, then kills the child with SIGKILL (sometimes while the disk is
full) and checks in a new process that every acked write is in the store; then the next cycle starts a
new child on the same store. It prints per cycle the writes acked and refused, and exits 1 on the
first acked write missing.

    sudo nice -n 10 python benchmarks/disk_full_kill.py --duration 300 --size-mb 40
"""

from __future__ import annotations

import argparse
import contextlib
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAD = "v" * 300


def child(store: Path, start: int, retry_s: float) -> None:
    sys.path.insert(0, str(ROOT))
    from twin.errors import StoreError
    from twin.graph import vocab
    from twin.graph.rdf import ChangeSet, RdfLiteral, Triple
    from twin.graph.store import EmbeddedStore
    from twin.live.store_health import WatchedStore

    st = WatchedStore(EmbeddedStore.open(store))
    i, tried, flushed = start, 0.0, time.monotonic()
    while True:
        if not st.health.ok:
            if time.monotonic() - tried > retry_s:
                tried = time.monotonic()
                st.recover()
            time.sleep(0.005)
            continue
        i += 1
        value = RdfLiteral(f"{PAD}{i}", vocab.XSD_STRING)
        revision = RdfLiteral(str(i), vocab.XSD_STRING)
        try:
            st.apply(
                ChangeSet(add=(Triple(f"urn:x:{i}", "urn:p", value),)),
                ChangeSet(remove=(("urn:m", "urn:rev"),), add=(Triple("urn:m", "urn:rev", revision),)),
            )
            print("ack", i, flush=True)
        except StoreError as err:
            print("refused", i, str(err)[:100], flush=True)
        if time.monotonic() - flushed > 1.0 and st.health.ok:
            flushed = time.monotonic()
            with contextlib.suppress(Exception):
                st.flush()
        time.sleep(0.003)


def held(store: Path, env: dict[str, str]) -> set[int]:
    """The writes the store holds, read by a new process (as after a restart)."""
    code = (
        "import sys, pyoxigraph as ox; s = ox.Store(sys.argv[1]); "
        "print(' '.join(str(q.subject.value).rsplit(':', 1)[1] "
        "for q in s.quads_for_pattern(None, ox.NamedNode('urn:p'), None)))"
    )
    argv = [sys.executable, "-c", code, str(store)]
    out = subprocess.run(argv, check=False, capture_output=True, text=True, env=env)
    if out.returncode != 0:
        raise RuntimeError(f"the store did not open: {out.stderr[-500:]}")
    return {int(x) for x in out.stdout.split()}


def fill(disk: Path) -> None:
    fd = os.open(disk / "filler", os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    for size in (1 << 16, 512, 1):
        with contextlib.suppress(OSError):
            while True:
                os.write(fd, b"\0" * size)
    os.close(fd)


def run(args: argparse.Namespace) -> int:
    work = Path(tempfile.mkdtemp(prefix="disk-full-kill-"))
    disk = work / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={args.size_mb}m", "tmpfs", str(disk)], check=True)
    store, rng = disk / "store", random.Random(args.seed)
    acked: set[int] = set()
    start, cycles, refused, lost = 0, 0, 0, []
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    try:
        end = time.monotonic() + args.duration
        while time.monotonic() < end and not lost:
            cycles += 1
            out = work / "child.out"
            with out.open("w") as f:
                p = subprocess.Popen(
                    [sys.executable, __file__, "--child", str(store), str(start), str(args.retry)],
                    stdout=f, stderr=subprocess.STDOUT, env=env,
                )  # fmt: skip
                time.sleep(rng.uniform(1.5, 3.0))
                for _ in range(rng.randint(0, 2)):
                    fill(disk)
                    time.sleep(rng.uniform(0.1, 1.5))
                    (disk / "filler").unlink()
                    time.sleep(rng.uniform(0.05, 1.5))
                if rng.random() < 0.3:  # killed while the disk is full
                    fill(disk)
                    time.sleep(rng.uniform(0.1, 1.0))
                p.kill()
                p.wait()
            with contextlib.suppress(FileNotFoundError):
                (disk / "filler").unlink()
            lines = out.read_text().splitlines()
            now = {int(x.split()[1]) for x in lines if x.startswith("ack ")}
            n_refused = sum(x.startswith("refused ") for x in lines)
            acked |= now
            refused += n_refused
            have = held(store, env)
            lost = sorted(acked - have)
            print(f"cycle {cycles}: {len(now)} acked, {n_refused} refused, {len(lost)} of {len(acked)} lost")
            start = max(acked | have | {start}) + 1000
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)
    print(
        f"{cycles} cycles, {len(acked)} writes acked, {refused} refused, {len(lost)} acked lost {lost[:10]}"
    )
    return 1 if lost else 0


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(Path(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]))
        return 0
    p = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    p.add_argument("--duration", type=float, default=300.0)
    p.add_argument(
        "--size-mb", type=int, default=40, help="the tmpfs (the store grows about 1 MB per 2,000 writes)"
    )
    p.add_argument("--retry", type=float, default=0.2, help="seconds between reopen attempts (the daemon: 2)")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    if os.geteuid() != 0:
        print(
            "disk_full_kill.py: the store's tmpfs is mounted by this script: run it as root", file=sys.stderr
        )
        return 2
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
