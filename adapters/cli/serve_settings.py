"""``[serve]``: how ``twin serve`` runs as a service. The CLI owns this table."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from twin.config import ConfigSection
from twin.config.base import Number, PathSetting


class ServeSettings(ConfigSection):
    """``[serve]``: the daemon's stop, and the route graph files it keeps up to date."""

    table = "serve"

    stop_timeout_s: Annotated[Number, Field(gt=0.0, le=3600.0)] = Field(
        10.0,
        description="How long a stop (SIGINT, SIGTERM) waits for queries in flight and threads to end; "
        "past it the daemon exits with code 124 after closing the store.",
    )
    batch_wait_ms: Annotated[Number, Field(ge=0.0, le=50.0)] = Field(
        2.0,
        description="Once the writer takes an observation, how long it waits for more to join it in one "
        "batch (one commit, one map pass, one update per map: robots that report at the same instants "
        "cost the daemon less), milliseconds; the observations wait that much longer for their acks. "
        "0: only what is queued.",
    )
    route_files: PathSetting | None = Field(
        None,
        description="A directory where the daemon writes each routes skill's <skill>.nav_graph.yaml and "
        "<storey>__<skill>.geojson at start and at every new graph version (default: not written).",
    )
