"""The daemon's current map once it shows a revision. A Zenoh ack leaves through the daemon's dispatcher
after the map updates it caused reached the holder that answers ``get_map``, but the ROS 2 ingestion's
counts and the status are told on the writer's thread, before: a map read right after them may be the
map as it was (on a loaded machine, for longer than any fixed sleep). Waiting on the revision also
replaces the fixed sleeps that were taken after Zenoh acks."""

from __future__ import annotations

import time
from collections.abc import Callable

from adapters.zenoh.client import TwinClient
from twin.maps.grid import OccupancyGrid

SETTLE_S = 30.0
"""How long a map may take to show a revision before the test fails (a quiet machine takes ms)."""


def settled(
    client: TwinClient,
    skill: str = "navigation",
    *,
    storey: str = "ground-floor",
    revision: int | None = None,
) -> tuple[OccupancyGrid, int, int]:
    """``(grid, revision, version)`` of the map once its revision (that of the last commit that changed
    it) is ``revision`` or later; by default the store's revision now, so call it only when the last
    commit changed this map, or when the map showed every commit since."""
    wanted = client.status()["revision"] if revision is None else revision
    deadline = time.monotonic() + SETTLE_S
    while True:
        grid, got, version = client.get_map(storey, skill)
        if got >= wanted:
            return grid, got, version
        assert time.monotonic() < deadline, (
            f"{storey}/{skill} at revision {got} after {SETTLE_S:.0f} s, not {wanted}"
        )
        time.sleep(0.05)


def settled_map(
    client: TwinClient, skill: str = "navigation", *, revision: int | None = None
) -> OccupancyGrid:
    """The ground floor's map of ``skill`` once it shows ``revision`` (:func:`settled`)."""
    return settled(client, skill, revision=revision)[0]


def map_where(
    client: TwinClient, test: Callable[[OccupancyGrid], bool], what: str, skill: str = "navigation"
) -> OccupancyGrid:
    """The ground floor's map of ``skill`` once ``test`` holds for it, for what has no acked revision
    to wait for (ROS ingest's own holds and lifetimes); fails naming ``what`` after :data:`SETTLE_S`."""
    deadline = time.monotonic() + SETTLE_S
    while True:
        grid, _, _ = client.get_map("ground-floor", skill)
        if test(grid):
            return grid
        assert time.monotonic() < deadline, f"the {skill} map did not come to show {what} in {SETTLE_S:.0f} s"
        time.sleep(0.05)
