"""The twin's status: what ``twin status`` and the ``status`` queryable answer.

Example::

    service_status(service)["revision"]     # 7
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.errors import StoreError
from twin.fusion.bias import detector_biases
from twin.fusion.clocks import clock_offsets
from twin.live.census import writer_sizes

if TYPE_CHECKING:
    from twin.live.service import TwinService


def _triples(service: TwinService) -> int | None:
    """The store's triple count (None: it cannot be counted now; not asked while it is unreachable,
    which would cost each status its time-out)."""
    if service.store_health.state == "unreachable":
        return None
    try:
        return len(service.store)
    except StoreError:
        return None


def _sizes(service: TwinService) -> dict[str, int]:
    """The writer's containers by name (:mod:`twin.live.census`); read off the writer's thread, so a
    container changing size under the walk costs this status its sizes, never the answer."""
    roots = {
        "live": service.live,
        "observer": service.observer,
        "publication": service.publication,
        "points_publication": service.points_publication,
    }
    for _ in range(3):
        try:
            return writer_sizes(roots)
        except RuntimeError:  # changed size during iteration: the writer ran
            continue
    return {}


def service_status(service: TwinService) -> dict[str, object]:
    """Site, revision, the store's state (``ok``, ``read-only: <reason>``, ``unreachable: <reason>``:
    see :mod:`twin.live.store_health`), element and triple counts, skills, storeys, every map's
    version, every points map's latest published cloud (version, size), observation counts, queue
    depth, the sizes of the writer's containers and uptime of a started service."""
    live = service.live
    obs = service.observer
    now = service.clock()
    triples = _triples(service)  # first: asking the store is what finds it unreachable
    states = list(live.states.values())  # (read off the writer's thread: one copy for both counts)
    removed = sum(1 for s in states if s.removed)
    return {
        "site": service.config.site,
        "revision": live.revision,
        "store": service.store_health.text,
        "elements": len(states) - removed,
        "triples": triples,
        "skills": sorted(live.skills),
        "storeys": [s.key for s in live.maps.scene.storeys],
        "maps": [
            {"storey": p.storey, "skill": p.skill, "version": p.version, "revision": p.revision}
            for p in sorted(service.published_maps(), key=lambda p: (p.storey, p.skill))
        ],
        "points": [
            {
                "storey": e.cloud.storey,
                "skill": e.cloud.skill,
                "version": e.version,
                "revision": e.revision,
                "points": len(e.cloud),
            }
            for e in sorted(
                list(service.points_publication.latest.values()),
                key=lambda e: (e.cloud.storey, e.cloud.skill),
            )
        ],
        "observations": {"accepted": obs.accepted, "unchanged": obs.unchanged, "rejected": obs.rejected},
        "fusion": {
            "aliases": len(live.fusion.aliases),
            "tracked": len(live.fusion.tracks),
            "tombstones": removed,
            "stale": obs.stale,
            "clock_offsets": clock_offsets(live.fusion),
            "detector_biases": detector_biases(live.fusion),
            **{k: obs.fusion_counts[k] for k in sorted(obs.fusion_counts)},
        },
        "queue_depth": service.queue_depth,
        "sizes": _sizes(service),
        "uptime_s": round((now - service.started_ns) / 1e9, 3),
    }
