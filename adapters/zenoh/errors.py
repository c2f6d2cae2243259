"""Errors of the Zenoh adapter, one per role. Messages name the offending value."""

from __future__ import annotations

from twin.errors import TwinError


class TransportError(TwinError):
    """A Zenoh session cannot be configured or opened, or a key expression is invalid."""


class RemoteError(TwinError):
    """The daemon answered a request with an error (the message is the daemon's)."""


class DaemonTimeoutError(TwinError):
    """The daemon did not answer in time (is it running, and reachable at the given endpoint?)."""


class StoreySwitchError(TwinError):
    """A robot's storey cannot be switched: unknown robot or storey (nothing changed)."""
