"""The route graphs' error: a routes skill that cannot make a graph (one line, naming the value)."""

from __future__ import annotations

from twin.errors import TwinError


class RouteError(TwinError):
    """A routes skill is invalid, or cannot make a graph of the building (e.g. a storey with no free
    space for its robot, a robot wider than every door)."""
