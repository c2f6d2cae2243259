"""A real full disk for the tests of a store that refuses writes: a small tmpfs, filled to the last
byte. Mounting needs root; where it cannot be mounted the test is skipped (the resource is absent)."""

from __future__ import annotations

import contextlib
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from twin.errors import StoreWriteError
from twin.graph.rdf import ChangeSet
from twin.graph.store import GraphStore
from twin.live.store_health import PROBE


@contextlib.contextmanager
def small_tmpfs(where: Path, size_mib: int = 16) -> Iterator[Path]:
    """A ``size_mib`` MiB tmpfs mounted at ``where`` (created), unmounted afterwards."""
    where.mkdir(parents=True, exist_ok=True)
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_mib}m", "tmpfs", str(where)],
                             capture_output=True, text=True, check=False)  # fmt: skip
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {mounted.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def fill_until_refused(disk: Path, store: GraphStore) -> Path:
    """Fill ``disk`` to the last byte, then until ``store`` refuses a write (its log's last page may take
    a write or two); returns the filler file (unlink it to free the space)."""
    filler = disk / "filler"
    with filler.open("wb", buffering=0) as f:
        for size in (1 << 16, 1):
            with contextlib.suppress(OSError):
                while True:
                    f.write(b"\0" * size)
    with contextlib.suppress(StoreWriteError):
        for _ in range(100):
            store.apply(ChangeSet(add=(PROBE,)), ChangeSet(delete=(PROBE,)))
    return filler
