"""A robot's map subscriber as its own process (for the integration tests).

Usage: python -m tests.integration.subscriber ENDPOINT OUT_DIR STOREY SKILL [SKILL ...]

Watches the maps, prints one JSON line per map version received (storey, skill, version, via), and on
EOF of stdin writes each map's final copy to OUT_DIR/<storey>__<skill>.npy and exits.
"""

from __future__ import annotations

import json
import sys
import threading
from pathlib import Path

import numpy as np

from adapters.zenoh.client import MapVersion, TwinClient


def main() -> int:
    endpoint, out, storey, *skills = sys.argv[1:]
    lock = threading.Lock()

    def on_version(v: MapVersion) -> None:
        with lock:
            line = {"storey": v.grid.storey, "skill": v.grid.skill, "version": v.version, "via": v.via}
            print(json.dumps(line), flush=True)

    with TwinClient.connect([endpoint]) as twin:
        watchers = [twin.watch(storey, skill, on_version) for skill in skills]
        with lock:  # versions may already be arriving on Zenoh's threads
            print(json.dumps({"ready": True}), flush=True)
        sys.stdin.read()  # until the test closes our stdin
        for w in watchers:
            if w.latest is not None:
                np.save(Path(out) / f"{storey}__{w.skill}.npy", w.latest.grid.data)
            w.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
