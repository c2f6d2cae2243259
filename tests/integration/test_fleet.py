"""Many robots, one twin, with the daemon as a process and robots as `twin observe` processes: one table
seen by three robots is one element across a restart, and its move leaves no ghost; a short fleet of
simulated robots with views leaves no duplicate and no ghost where it looked."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from adapters.zenoh.client import TwinClient
from tests.integration.conftest import Daemon, start_daemon, twin
from tests.integration.settled import settled_map
from twin.maps.grid import OCCUPIED

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

ROOT = Path(__file__).resolve().parents[2]


def observe(d: Daemon, robot: str, iri: str, box: str) -> dict[str, object]:
    r = twin(
        "observe", "--connect", d.endpoint, "--robot", robot, "--id", iri, "--box", box,
        "--class", "IfcFurniture", "--storey", "ground-floor", timeout=60,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    ack: dict[str, object] = json.loads(r.stdout[r.stdout.index("{") :])
    return ack


def cell(client: TwinClient, x: float, y: float) -> int:
    """The ground floor's navigation cell at ``(x, y)`` once the map shows the store's revision (after a
    ROS 2 report counted in the status; a Zenoh ack comes after its map update): call it when the last
    commit changed that map, or when the map shows every commit since."""
    grid = settled_map(client)
    f = grid.frame
    return int(grid.data[int((y - f.origin_y) / f.resolution_m), int((x - f.origin_x) / f.resolution_m)])


def test_three_robots_one_table_one_element_across_a_restart_and_its_move_leaves_no_ghost(
    fresh_store: Path,
) -> None:
    d = start_daemon(fresh_store, "--no-record")
    try:
        first = observe(d, "robot1", "urn:robot1:table-1", "16.6,7.0,0.375,1.2,0.8,0.75,0.0")
        assert first["upserted"] == ["urn:robot1:table-1"]
        second = observe(d, "robot2", "urn:robot2:obj-77", "16.62,7.01,0.375,1.2,0.8,0.75,0.01")
        assert second["resolved"] == {"urn:robot2:obj-77": "urn:robot1:table-1"} and second["unchanged"]
        assert d.stop()[0] == 0
        d = start_daemon(fresh_store, "--no-record")  # the alias survives the restart
        third = observe(d, "robot3", "urn:robot3:t", "16.58,6.99,0.375,0.8,1.2,0.75,1.58")
        assert third["resolved"] == {"urn:robot3:t": "urn:robot1:table-1"} and third["unchanged"]
        again = observe(d, "robot2", "urn:robot2:obj-77", "16.61,7.0,0.375,1.2,0.8,0.75,0.0")
        assert again["resolved"] == {"urn:robot2:obj-77": "urn:robot1:table-1"}
        with TwinClient.connect([d.endpoint]) as client:
            assert cell(client, 16.6, 7.0) == OCCUPIED
            moved = observe(d, "robot1", "urn:robot1:table-1", "12.0,7.0,0.375,1.2,0.8,0.75,0.0")
            assert "unchanged" not in moved
            assert cell(client, 16.6, 7.0) != OCCUPIED and cell(client, 12.0, 7.0) == OCCUPIED
            rows = client.sparql(
                'SELECT ?e WHERE { ?e twin:ifcClass "IfcFurniture" . '
                "FILTER NOT EXISTS { ?e twin:removed true } }"
            )
            assert isinstance(rows, dict)
            assert [b["e"]["value"] for b in rows["results"]["bindings"]] == ["urn:robot1:table-1"]
    finally:
        d.stop()


def test_a_short_fleet_leaves_no_duplicate_and_no_ghost_where_robots_looked() -> None:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import fleet_sim  # benchmarks/ is not a package

    args = fleet_sim.parser().parse_args(
        ["--robots", "3", "--objects", "6", "--duration", "30", "--moves", "1", "--removals", "1",
         "--p-false", "0", "--seed", "3"]
    )  # fmt: skip
    result = fleet_sim.run(args)
    final = result["final"]
    assert final["duplicates"] == 0, result
    assert final["viewed_ghosts"] == 0, result
    assert result["errors"] == 0
    assert result["acked_observations"] > 100
