"""The collector pause: off inside, as found after (errors and nesting included), on in a forked child."""

from __future__ import annotations

import gc
import multiprocessing as mp

import pytest

from twin.gc_pause import paused_gc


def _report(queue: mp.Queue) -> None:  # type: ignore[type-arg]
    queue.put(gc.isenabled())


def test_the_collector_is_off_inside_and_as_found_after() -> None:
    assert gc.isenabled()
    with paused_gc():
        assert not gc.isenabled()
        with paused_gc():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the inner pause leaves it to the outer one
    assert gc.isenabled()
    with pytest.raises(ValueError, match="inside"), paused_gc():
        raise ValueError("inside")
    assert gc.isenabled()
    gc.disable()
    try:
        with paused_gc():
            pass
        assert not gc.isenabled()  # off before, off after
    finally:
        gc.enable()


def test_a_child_forked_during_a_pause_collects() -> None:
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    with paused_gc():
        child = ctx.Process(target=_report, args=(queue,))
        child.start()
        child.join(30)
    assert queue.get(timeout=30) is True
    assert child.exitcode == 0
