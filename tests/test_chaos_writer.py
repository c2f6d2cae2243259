"""``benchmarks/chaos.py`` counts what the acks name. Its one "acked change lost" in a 10-minute run was
its writer's probe minted where the twin still held another probe (one whose removal a fault had
refused): the add resolved to that probe (association), the removal went through the alias and removed
it, and the writer then looked for ``twin:removed`` on its own probe's IRI, which is only an alias."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from tests.twin.live_helpers import PREFIX, box_turtle, observe, started

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import chaos  # benchmarks/ is not a package

PROBE = {"sx": 0.5, "sy": 0.5, "sz": 0.6}


def test_a_probe_resolved_to_a_held_table_is_counted_by_the_element_its_acks_name() -> None:
    service, _ = started()

    def sparql(query: str) -> dict[str, Any]:
        value: dict[str, Any] = json.loads(service.query(query)[1])
        return value

    writer, acks = chaos.Writer(), []

    def step(iri: str, payload: bytes) -> dict[str, Any]:
        ack = observe(service, "chaos-writer", payload).body
        assert ack["ok"], ack
        acks.append(chaos.Ack.of("chaos-writer", ack))
        writer.noted(iri, ack)
        return ack

    step("urn:chaos:probe-1", box_turtle("urn:chaos:probe-1", 5.0, 5.0, **PROBE))
    writer.current = None  # its removal refused (a full disk): the writer mints a new probe next
    added = step("urn:chaos:probe-2", box_turtle("urn:chaos:probe-2", 5.1, 5.05, **PROBE))
    assert added["resolved"] == {"urn:chaos:probe-2": "urn:chaos:probe-1"} and added["upserted"] == []
    gone = step("urn:chaos:probe-2", (PREFIX + "<urn:chaos:probe-2> twin:removed true .").encode())
    assert gone["removed"] == ["urn:chaos:probe-1"]

    assert writer.resolved == {"urn:chaos:probe-2": "urn:chaos:probe-1"}
    assert [i for i, _ in writer.removed] == ["urn:chaos:probe-1"]
    assert chaos.lost_removals(sparql, writer.removed, acks) == []
    assert chaos.lost_upserts(sparql, acks) == []
    # the probe's own IRI is an alias, never removed: counting it was the false loss
    late = acks[-1].at + 1.0
    assert chaos.lost_removals(sparql, [("urn:chaos:probe-2", late)], acks) == ["urn:chaos:probe-2"]
    held = chaos.what_the_store_holds(sparql, "urn:chaos:probe-2")
    assert [r["p"]["value"] for r in held] == ["https://w3id.org/building-twin#aliasOf"]
