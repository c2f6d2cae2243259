"""The Zenoh outbox makes the writer's sends in order, off its thread, and loses none on close."""

from __future__ import annotations

import threading

import pytest

from adapters.zenoh.outbox import Outbox


def test_sends_are_made_in_the_order_they_were_queued_on_the_outbox_thread() -> None:
    outbox = Outbox()
    seen: list[tuple[int, str]] = []
    for i in range(200):
        outbox.put(lambda i=i: seen.append((i, threading.current_thread().name)))
    assert outbox.drain()
    assert [i for i, _ in seen] == list(range(200))
    assert {name for _, name in seen} == {"zenoh-outbox"}
    outbox.close()


def test_a_failing_send_is_logged_and_the_next_ones_are_still_made(caplog: pytest.LogCaptureFixture) -> None:
    outbox = Outbox()
    seen: list[int] = []

    def boom() -> None:
        raise RuntimeError("the session is gone")

    outbox.put(boom)
    outbox.put(lambda: seen.append(1))
    outbox.close()
    assert seen == [1]
    assert "A Zenoh send failed" in caplog.text


def test_close_makes_every_queued_send_and_later_sends_run_at_once() -> None:
    outbox = Outbox()
    gate = threading.Event()
    seen: list[int] = []
    outbox.put(gate.wait)
    for i in range(50):
        outbox.put(lambda i=i: seen.append(i))
    assert outbox.depth >= 50
    gate.set()
    outbox.close()
    assert seen == list(range(50))
    outbox.put(lambda: seen.append(99))  # after close: on the caller's thread
    assert seen[-1] == 99
