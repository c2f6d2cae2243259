"""The recorder process: ``python -m adapters.rerun.child``, started by :class:`RerunRecorder`.

It owns the Rerun SDK (a :class:`RecordingWriter`), so logging, Arrow encoding and compression never
take the daemon's GIL. It reads length-prefixed pickled messages on stdin, in order:
``("open", options, max_failures, log_level)``, ``("event", event)``, ``("note", text, level)`` (a line
in the recording's event log), ``("set", attribute, value)``,
``("sync", n)``, ``("close",)``; and answers each ``sync`` and the end with one JSON line on its own
stdout: ``{"sync": n, "files": [...], "failures": k, "disabled": bool}``. End of input closes the file
too (the daemon died), so a recording is never left unflushed. A failing event is logged and counted;
after ``max_failures`` the writer stops recording (the daemon keeps running).
"""

from __future__ import annotations

import json
import logging
import os
import signal
import sys
from typing import IO

from adapters.rerun.pipe import read_message
from adapters.rerun.writer import RecordingWriter

log = logging.getLogger("adapters.rerun.recorder")


def serve(source: IO[bytes], replies: IO[str]) -> int:
    writer: RecordingWriter | None = None
    failures, max_failures, disabled = 0, 20, False

    def reply(**fields: object) -> None:
        files = [str(p) for p in writer.files] if writer is not None else []
        replies.write(
            json.dumps({**fields, "files": files, "failures": failures, "disabled": disabled}) + "\n"
        )
        replies.flush()

    while (message := read_message(source)) is not None:
        kind = message[0]
        if kind == "open":
            writer, max_failures = RecordingWriter(**message[1]), message[2]
            logging.getLogger().setLevel(message[3])  # as verbose as the daemon
        elif kind == "event" and writer is not None and not disabled:
            try:
                writer.write(message[1])
            except Exception:
                failures += 1
                log.exception("Recording %s failed", type(message[1]).__name__)
                if failures >= max_failures:
                    disabled = True
                    log.error("The Rerun recorder is disabled after %d failures", failures)
        elif kind == "note" and writer is not None and not disabled:
            writer.note(message[1], message[2])
        elif kind == "set" and writer is not None:
            setattr(writer, message[1], message[2])
        elif kind == "sync":
            reply(sync=message[1])
        elif kind == "close":
            break
    if writer is not None:
        try:
            writer.close()
        except Exception:
            log.exception("Closing the Rerun recording failed")
    reply(closed=True)
    return 0


def main() -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the daemon decides when recording ends
    os.nice(10)  # on a busy machine the daemon's map updates go first; recording can wait
    replies = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # whatever the SDK prints goes to stderr, not into the replies
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    return serve(sys.stdin.buffer, replies)


if __name__ == "__main__":
    sys.exit(main())
