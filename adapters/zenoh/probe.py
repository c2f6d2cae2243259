"""Why a Zenoh session reached nobody: a TCP probe of each ``tcp/`` and ``tls/`` endpoint tells a port
where nothing listens from a listener that accepted the connection and then refused the session (a
wrong user or password, a certificate of another authority, a daemon that requires credentials).

Zenoh reports both the same way (``Unable to connect to any of [...]``, or a session linked to nobody);
the probe is made only after that failure, so it costs nothing on the path that works.

Example::

    print(explain_unreachable(["tcp/127.0.0.1:7447"]))
    # nothing listens at tcp/127.0.0.1:7447 (connection refused): is 'twin serve' or the router running?
"""

from __future__ import annotations

import re
import socket
from collections.abc import Sequence

PROBE_S = 1.0
"""How long one TCP connect of the probe may take."""

_ENDPOINT = re.compile(r"^(?P<proto>tcp|tls)/(?:\[(?P<v6>[^\]]+)\]|(?P<host>[^:/#?]+)):(?P<port>\d+)")


def probe(endpoint: str, *, timeout_s: float = PROBE_S) -> str | None:
    """``"listening"``, ``"refused"`` (nothing listens), ``"unreachable: <why>"``, or None when the
    endpoint is not ``tcp/`` or ``tls/`` (not probed)."""
    m = _ENDPOINT.match(endpoint)
    if m is None:
        return None
    host = m["v6"] or m["host"]
    try:
        with socket.create_connection((host, int(m["port"])), timeout=timeout_s):
            return "listening"
    except ConnectionRefusedError:
        return "refused"
    except OSError as err:
        return f"unreachable: {err.strerror or err}"


def explain_unreachable(endpoints: Sequence[str], *, credentials: bool, tls: bool) -> str:
    """One sentence on why ``endpoints`` gave no session, from a probe of each.

    ``credentials``/``tls``: whether this side presented a user and password / uses TLS endpoints with
    a certificate, so that the sentence names what was refused."""
    parts: list[str] = []
    for endpoint in endpoints:
        state = probe(endpoint)
        if state == "listening":
            offered = []
            if credentials:
                offered.append("the user and password ([zenoh.auth])")
            if tls or endpoint.startswith("tls/"):
                offered.append("the certificates ([zenoh.tls]: the authority both sides trust)")
            what = (
                " and ".join(offered)
                if offered
                else "whether it requires credentials ([zenoh.auth] user and password_file) or TLS"
            )
            parts.append(
                f"{endpoint} accepted the connection but refused the Zenoh session: check {what} "
                "(or it is not a Zenoh endpoint)"
            )
        elif state == "refused":
            parts.append(
                f"nothing listens at {endpoint} (connection refused): is 'twin serve' or the router running?"
            )
        elif state is not None:
            parts.append(f"{endpoint} is {state}")
    return "; ".join(parts)
