"""A read-only view of two mappings, the first shadowing the second: what a batch changed over what the
twin holds.

It reads as ``collections.ChainMap(top, base)`` (the same keys, values and order) for the lookups the
writer makes per observation, at the cost of one or two dict lookups: ``ChainMap.get`` and ``in`` go
through a generator over its maps (a few microseconds each, many times per observation).

Example::

    current = Layered(batch_states, live.states)
    state = current.get(iri)
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TypeVar, overload

K = TypeVar("K")
V = TypeVar("V")
D = TypeVar("D")

_MISSING = object()


class Layered(Mapping[K, V]):
    """``top`` over ``base``, read-only: a key of ``top`` hides the same key of ``base``."""

    __slots__ = ("base", "top")

    def __init__(self, top: Mapping[K, V], base: Mapping[K, V]) -> None:
        self.top = top
        self.base = base

    def __getitem__(self, key: K) -> V:
        v = self.top.get(key, _MISSING)
        return self.base[key] if v is _MISSING else v  # type: ignore[return-value]

    @overload
    def get(self, key: K, /) -> V | None: ...
    @overload
    def get(self, key: K, /, default: V | D) -> V | D: ...
    def get(self, key: K, default: object = None) -> object:
        v = self.top.get(key, _MISSING)
        return self.base.get(key, default) if v is _MISSING else v

    def __contains__(self, key: object) -> bool:
        return key in self.top or key in self.base

    def __iter__(self) -> Iterator[K]:
        """The keys in ``ChainMap(top, base)``'s order: ``base``'s, then those only in ``top``."""
        yield from self.base
        yield from (k for k in self.top if k not in self.base)

    def __len__(self) -> int:
        return len(self.base) + sum(1 for k in self.top if k not in self.base)
