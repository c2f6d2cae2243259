"""``diagnostic_msgs/msg/DiagnosticArray`` of the ROS 2 ingestion: one ``DiagnosticStatus`` per robot or
source, what ``rqt_robot_monitor`` and the diagnostic aggregator show.

Each status is named ``twin_ingest: <owner>``; its level is WARN when messages were refused since the
previous array, else OK; its message says what happened, its values are the counts (received,
submitted, accepted, unchanged, refused and ignored by cause) and the last refusal.

Example::

    payload = encode_diagnostics([IngestDiagnostic("robot1", 0, "ok", {"accepted": "3"})], stamp_ns=now)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from adapters.ros.cdr import _header, _serialize, _typestore
from adapters.ros.interfaces import DIAGNOSTIC_ARRAY

__all__ = ["ERROR", "OK", "WARN", "IngestDiagnostic", "encode_diagnostics"]

OK, WARN, ERROR = 0, 1, 2


@dataclass(frozen=True, slots=True)
class IngestDiagnostic:
    owner: str
    level: int
    message: str
    values: Mapping[str, str]


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
