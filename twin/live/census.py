"""How big the writer's in-memory state is: the length of every container it holds, by name.

A daemon runs all day, so nothing it keeps may grow with how often an element is seen. The census
walks the writer's objects (the live state, fusion's memory, the observer, the publications) and
counts every dict, list, set and deque it finds, a few levels deep; a container of records (fusion's
tracks, the held triples) is summed over its records (``fusion.tracks[*].robots``: every track's
robots together). ``twin status`` carries it as ``sizes``; ``benchmarks/soak.py --census`` compares
two moments of a run.

Example::

    sizes = writer_sizes({"live": service.live, "observer": service.observer})
    sizes["fusion.history[*]"]      # past poses kept, all elements together
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from typing import Any

_CONTAINERS = (dict, list, set, frozenset, deque)
_SKIP = frozenset({"maps", "scene", "site", "store", "config", "emit", "send", "clock", "skills"})
"""Attributes the census does not enter: the geometry (arrays, not per-observation state), the
configuration, and callables."""
_FLAT = frozenset({"states"})
"""Containers counted but not summed over: a record per element of the whole building (a status on a
large building would walk every one), and nothing in them grows with sightings."""


def _fields(obj: object) -> list[tuple[str, Any]]:
    """The attributes of ``obj`` (dataclass slots or instance dict), none of the skipped ones."""
    names: list[str] = []
    for cls in type(obj).__mro__:
        names += [n for n in getattr(cls, "__slots__", ()) if isinstance(n, str)]
    names += list(getattr(obj, "__dict__", {}))
    out = []
    for name in dict.fromkeys(names):
        if name.lstrip("_") in _SKIP or name.startswith("__"):
            continue
        try:
            out.append((name.lstrip("_"), getattr(obj, name)))
        except AttributeError:
            continue
    return out


def _is_record(value: object) -> bool:
    return hasattr(value, "__slots__") or hasattr(value, "__dataclass_fields__")


def _walk(obj: object, prefix: str, out: dict[str, int], depth: int) -> None:
    for name, value in _fields(obj):
        key = f"{prefix}{name}"
        if isinstance(value, _CONTAINERS):
            out[key] = out.get(key, 0) + len(value)
            if depth > 0 and name not in _FLAT:
                items = value.values() if isinstance(value, dict) else value
                _walk_items(items, f"{key}[*]", out, depth - 1)
        elif _is_record(value) and depth > 0 and not isinstance(value, type):
            _walk(value, f"{key}.", out, depth - 1)


def _walk_items(items: Any, key: str, out: dict[str, int], depth: int) -> None:
    """Sum over the values of a container: their lengths (containers) or their fields (records)."""
    for item in list(items)[:100_000]:
        if isinstance(item, _CONTAINERS):
            out[key] = out.get(key, 0) + len(item)
        elif _is_record(item):
            _walk(item, f"{key}.", out, depth)
        else:
            return  # plain values: the container's own length says it all


def writer_sizes(roots: Mapping[str, object], *, depth: int = 2) -> dict[str, int]:
    """``name.attribute[.attribute...]`` -> length, for every container under ``roots`` (``[*]``: summed
    over a container's values); sorted by name, empty containers left out."""
    out: dict[str, int] = {}
    for name, obj in roots.items():
        _walk(obj, f"{name}.", out, depth)
    return {k: v for k, v in sorted(out.items()) if v}
