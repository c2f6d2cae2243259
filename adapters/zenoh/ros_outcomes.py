"""What an ingest worker makes of a robot's message (:data:`Outcome`): an array translated, a message
refused, an array waiting for its transform. The daemon's side reads them
(:mod:`adapters.zenoh.ros_workers`, :mod:`adapters.zenoh.ros_hold`)."""

from __future__ import annotations

from dataclasses import dataclass

from adapters.ros.observation_doc import Translation
from adapters.ros.sessions import TrackerSession

__all__ = ["Outcome", "Refused", "Translated", "Waited"]


@dataclass(frozen=True, slots=True)
class Translated:
    owner: str
    translation: Translation
    received_ns: int
    session: TrackerSession | None = None
    """The robot's tracker session after this array (a copy when it comes from a worker)."""

    def __reduce__(self) -> tuple[type[Translated], tuple[object, ...]]:
        """A call with its fields (one per array from a worker; a frozen dataclass's setstate is slower)."""
        return (Translated, (self.owner, self.translation, self.received_ns, self.session))


@dataclass(frozen=True, slots=True)
class Refused:
    owner: str
    cause: str
    message: str


@dataclass(frozen=True, slots=True)
class Waited:
    owner: str


Outcome = Translated | Refused | Waited
