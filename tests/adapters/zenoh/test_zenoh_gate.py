"""The callback gate: close lets no new callback in and waits for the running ones."""

from __future__ import annotations

import threading

from adapters.zenoh.gate import CallbackGate


def test_close_waits_for_a_running_callback_and_lets_no_new_one_in() -> None:
    gate = CallbackGate()
    inside, release = threading.Event(), threading.Event()
    seen: list[str] = []

    def slow(arg: str) -> None:
        inside.set()
        release.wait(5)
        seen.append(arg)

    wrapped = gate.wrap(slow)
    release.set()
    wrapped("before")  # a callback that ended before the close never holds it
    release.clear()
    inside.clear()
    worker = threading.Thread(target=wrapped, args=("running",))
    worker.start()
    assert inside.wait(5)
    threading.Timer(0.05, release.set).start()
    assert gate.close(timeout_s=5) == 0  # woken when the running one ended, not at the deadline
    assert seen == ["before", "running"]
    wrapped("after")
    assert seen == ["before", "running"]
    worker.join()


def test_close_gives_up_at_its_deadline_and_says_how_many_still_run() -> None:
    gate = CallbackGate()
    inside, release = threading.Event(), threading.Event()
    wrapped = gate.wrap(lambda _: (inside.set(), release.wait(5)))
    worker = threading.Thread(target=wrapped, args=(None,))
    worker.start()
    assert inside.wait(5)
    assert gate.close(timeout_s=0.05) == 1
    release.set()
    worker.join()
    assert gate.running == 0
