"""The live twin: the single writer that applies robots' observations and keeps every map current.

- :mod:`twin.live.service`: :class:`TwinService`, the writer's loop, start-up and status;
- :mod:`twin.live.observe`: the hot path, a batch of observations from payload to acks;
- :mod:`twin.live.plan`: one observation checked against the twin, as the triples it changes;
- :mod:`twin.live.membership`: which skills select a changed element, from memory;
- :mod:`twin.live.live_maps`: every (storey, skill) map, re-rendered where it changed;
- :mod:`twin.live.state`: what the writer holds of each element;
- :mod:`twin.live.skill_changes`: skills added and removed at run time;
- :mod:`twin.live.query`: read-only SPARQL with its bounds;
- :mod:`twin.live.requests`: requests and replies.
"""

from twin.live.publication import PublishedVersion
from twin.live.requests import Reply
from twin.live.service import TwinService

__all__ = ["PublishedVersion", "Reply", "TwinService"]
