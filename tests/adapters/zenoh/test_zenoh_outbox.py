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


def test_joined_sends_queued_in_a_row_run_as_one_job_and_never_overtake_a_put() -> None:
    outbox = Outbox()
    gate = threading.Event()
    seen: list[int] = []
    outbox.put(gate.wait)
    outbox.join(lambda: seen.append(1))
    outbox.put(lambda: seen.append(2))
    for i in (3, 4, 5):
        outbox.join(lambda i=i: seen.append(i))
    assert outbox.depth == 4  # the gate, [1], 2, [3, 4, 5]
    gate.set()
    assert outbox.drain()
    outbox.join(lambda: seen.append(6))  # the group taken: a new one
    outbox.close()
    assert seen == [1, 2, 3, 4, 5, 6]


def test_a_failing_joined_send_is_logged_and_the_others_of_its_group_are_still_made(
    caplog: pytest.LogCaptureFixture,
) -> None:
    outbox = Outbox()
    gate = threading.Event()
    seen: list[int] = []

    def boom() -> None:
        raise RuntimeError("the query is gone")

    outbox.put(gate.wait)
    outbox.join(lambda: seen.append(1))
    outbox.join(boom)
    outbox.join(lambda: seen.append(3))
    gate.set()
    outbox.close()
    assert seen == [1, 3]
    assert "A Zenoh send failed" in caplog.text


def test_a_holders_sends_gather_until_it_lets_go_and_another_threads_put_hands_them_on_first() -> None:
    outbox = Outbox()
    seen: list[str] = []
    outbox.hold()
    outbox.put(lambda: seen.append("update"))
    outbox.join(lambda: seen.append("ack 1"))
    outbox.join(lambda: seen.append("ack 2"))
    assert outbox.depth == 0  # gathered: the outbox's thread was not woken
    outbox.release()
    assert outbox.drain()
    assert seen == ["update", "ack 1", "ack 2"]
    outbox.hold()
    outbox.join(lambda: seen.append("ack 3"))
    other = threading.Thread(target=outbox.put, args=(lambda: seen.append("other thread"),))
    other.start()
    other.join()
    outbox.join(lambda: seen.append("ack 4"))
    assert outbox.drain(timeout_s=5)  # the holder's own drain sends what it gathered: no wait for release
    assert seen[3:] == ["ack 3", "other thread", "ack 4"]
    outbox.release()
    outbox.close()
