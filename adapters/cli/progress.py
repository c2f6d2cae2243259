"""Progress bars on the terminal (rich), for long work such as meshing a large model.

Nothing is drawn when stderr is not a terminal (CI, pipes), so logs stay clean.

Example::

    with progress_bar("meshing") as advance:
        read_model(path, progress=advance)      # advance(done, total)
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

Advance = Callable[[int, int], None]


@contextmanager
def progress_bar(label: str, *, console: Console | None = None) -> Iterator[Advance]:
    """A ``(done, total)`` callback drawing one bar on ``console`` (default: stderr) while the block runs."""
    console = console or Console(stderr=True)
    if not console.is_terminal:
        yield lambda done, total: None
        return
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
