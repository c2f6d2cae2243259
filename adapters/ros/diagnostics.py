"""What the ROS 2 ingestion counts per robot or source (:class:`Counts`, in the daemon's status) and the
``diagnostic_msgs/msg/DiagnosticArray`` it publishes of them: one ``DiagnosticStatus`` per robot or
source, what ``rqt_robot_monitor`` and the diagnostic aggregator show.

Each status is named ``twin_ingest: <owner>``; its level is WARN when messages were refused since the
previous array, else OK; its message says what happened, its values are the counts (received,
submitted, accepted, unchanged, refused and ignored by cause) and the last refusal.

Example::

    payload = encode_diagnostics([IngestDiagnostic("robot1", 0, "ok", {"accepted": "3"})], stamp_ns=now)
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from adapters.ros.cdr import _header, _serialize, _typestore
from adapters.ros.interfaces import DIAGNOSTIC_ARRAY

__all__ = ["ERROR", "OK", "WARN", "Counts", "IngestDiagnostic", "encode_diagnostics"]

OK, WARN, ERROR = 0, 1, 2


@dataclass(frozen=True, slots=True)
class IngestDiagnostic:
    owner: str
    level: int
    message: str
    values: Mapping[str, str]


@dataclass(slots=True)
class Counts:
    """One robot's or source's ingestion, for the status."""

    received: int = 0
    messages: Counter[str] = field(default_factory=Counter)
    waited: int = 0
    submitted: int = 0
    accepted: int = 0
    unchanged: int = 0
    refused: Counter[str] = field(default_factory=Counter)
    overflow: Counter[str] = field(default_factory=Counter)
    """Messages dropped because the ingestion queue was full, by kind (also in ``refused["overflow"]``)."""
    ignored: Counter[str] = field(default_factory=Counter)
    last_refusal: str | None = None
    last_refusal_ns: int | None = None
    logged: set[str] = field(default_factory=set)

    def diagnostic(self, owner: str, *, refused_before: int) -> IngestDiagnostic:
        """The status of ``owner``: WARN when more were refused than ``refused_before``."""
        refused = sum(self.refused.values())
        values = {key: str(getattr(self, key)) for key in ("received", "submitted", "accepted", "unchanged")}
        values |= {f"refused.{k}": str(v) for k, v in sorted(self.refused.items())}
        values |= {f"ignored.{k}": str(v) for k, v in sorted(self.ignored.items())}
        if self.last_refusal:
            values["last_refusal"] = self.last_refusal
        message = f"accepted {self.accepted}, unchanged {self.unchanged}, refused {refused}"
        fresh = refused - refused_before
        if fresh:
            message += f" ({fresh} since the last report; last: {self.last_refusal})"
        return IngestDiagnostic(owner, WARN if fresh else OK, message, values)

    def as_dict(self) -> dict[str, object]:
        return {
            "received": self.received,
            "messages": dict(sorted(self.messages.items())),
            "waited_for_tf": self.waited,
            "submitted": self.submitted,
            "accepted": self.accepted,
            "unchanged": self.unchanged,
            "refused": dict(sorted(self.refused.items())),
            "overflow": dict(sorted(self.overflow.items())),
            "ignored": dict(sorted(self.ignored.items())),
            "last_refusal": self.last_refusal,
            "last_refusal_ns": self.last_refusal_ns,
        }


def encode_diagnostics(statuses: Sequence[IngestDiagnostic], *, stamp_ns: int, frame_id: str = "") -> bytes:
    """A CDR DiagnosticArray of ``statuses``."""
    types = _typestore().types
    status, key_value = types["diagnostic_msgs/msg/DiagnosticStatus"], types["diagnostic_msgs/msg/KeyValue"]
    message = types[DIAGNOSTIC_ARRAY](
        header=_header(stamp_ns, frame_id),
        status=[
            status(
                level=s.level,
                name=f"twin_ingest: {s.owner}",
                message=s.message,
                hardware_id="",
                values=[key_value(key=k, value=v) for k, v in s.values.items()],
            )
            for s in statuses
        ],
    )
    return _serialize(message, DIAGNOSTIC_ARRAY)
