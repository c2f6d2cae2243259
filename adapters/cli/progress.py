"""Progress on the terminal (rich), for long work such as meshing a large model or building maps.

On a terminal, a bar; when stderr is not a terminal (CI, pipes, a log file), one line as the phase
starts and one as it ends, so that a log shows what the command was doing without a bar's redraws
(and without importing the bar: 0.15 s of a daemon's start).

Example::

    with progress_bar("meshing") as advance:
        read_model(path, progress=advance)      # advance(done, total)
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console

Advance = Callable[[int, int], None]


@contextmanager
def progress_bar(label: str, *, unit: str = "", console: Console | None = None) -> Iterator[Advance]:
    """A ``(done, total)`` callback drawing one bar on ``console`` (default: stderr) while the block
    runs; ``unit`` names what is counted, in the lines printed instead of a bar."""
    console = console or Console(stderr=True)
    if not console.is_terminal:
        with _progress_lines(label, unit, console) as advance:
            yield advance
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=console, transient=False) as bar:
        task = bar.add_task(label, total=None)

        def advance(done: int, total: int) -> None:
            bar.update(task, completed=done, total=max(total, 1))

        yield advance


@contextmanager
def _progress_lines(label: str, unit: str, console: Console) -> Iterator[Advance]:
    """``meshing: 1,660 elements ...`` when the work is first reported, ``meshing: 1,660 of 1,660
    elements in 8.2 s`` at the end (nothing if no work was reported)."""
    unit = f" {unit}" if unit else ""
    state = {"done": 0, "total": 0}
    t0 = time.perf_counter()

    def advance(done: int, total: int) -> None:
        if not state["total"] and total > 0:
            console.print(f"{label}: {total:,}{unit} ...", highlight=False, soft_wrap=True)
        state["done"], state["total"] = done, max(total, state["total"])

    yield advance
    if state["total"]:
        seconds = time.perf_counter() - t0
        line = f"{label}: {state['done']:,} of {state['total']:,}{unit} in {seconds:.1f} s"
        console.print(line, highlight=False, soft_wrap=True)
