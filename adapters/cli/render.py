"""What the daemon answers, as an operator reads it: ``twin status`` and ``twin explain`` in text.

Times in nanoseconds since the epoch (``*_ns``, ``*_at``) become local times; sections this module does
not know (another version of the daemon may add some) are rendered generically, a line a value, so a
new key shows up readable rather than as JSON. ``--json`` prints the daemon's JSON as it is.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

EPOCH_NS_MIN = 10**17
"""Below this an ``*_ns`` value is a duration, not a time since the epoch (1973)."""


def local_time(ns: int) -> str:
    """``2026-11-28 10:15:03.120 CET``: an epoch time in nanoseconds, in this machine's time zone."""
    t = dt.datetime.fromtimestamp(ns / 1e9, tz=dt.UTC).astimezone()
    return f"{t:%Y-%m-%d %H:%M:%S}.{t.microsecond // 1000:03d} {t:%Z}"


def duration(seconds: float) -> str:
    """``42.1 s``, ``3 min 5 s``, ``2 h 3 min``."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, s = divmod(int(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {s} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes} min"


def _label(key: str) -> str:
    return key.removesuffix("_ns").removesuffix("_s").replace("_", " ")


def scalar(key: str, value: Any) -> str:
    """One value as text: epoch nanoseconds as a local time, seconds as a duration."""
    if isinstance(value, bool) or value is None:
        return {True: "yes", False: "no", None: "none"}[value]
    if key.endswith("_ns") and isinstance(value, int):
        return local_time(value) if value >= EPOCH_NS_MIN else duration(value / 1e9)
    if key.endswith("_s") and isinstance(value, int | float):
        return duration(float(value))
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _flat(value: Any) -> bool:
    if isinstance(value, dict):
        return all(not isinstance(v, dict | list) for v in value.values())
    if isinstance(value, list):
        return all(not isinstance(v, dict | list) for v in value)
    return True


def inline(value: dict[str, Any]) -> str:
    """A flat mapping on one line: ``storey ground-floor, switches 2, switched 2026-11-28 10:15:03``."""
    return ", ".join(f"{_label(k)} {scalar(k, v)}" for k, v in value.items()) or "none"


def generic(key: str, value: Any, indent: str = "") -> list[str]:
    """Any value under ``key`` as lines: scalars and flat lists on one line, mappings nested."""
    if isinstance(value, list):
        if _flat(value):
            return [f"{indent}{_label(key)}: {', '.join(scalar(key, v) for v in value) or 'none'}"]
        lines = [f"{indent}{_label(key)} ({len(value)}):"]
        for item in value:
            if isinstance(item, dict) and _flat(item):
                lines.append(f"{indent}  {inline(item)}")
            else:
                lines += generic("-", item, indent + "  ")
        return lines
    if isinstance(value, dict):
        if _flat(value):
            return [f"{indent}{_label(key)}: {inline(value)}"]
        lines = [f"{indent}{_label(key)}:"]
        for k, v in value.items():
            lines += generic(k, v, indent + "  ")
        return lines
    return [f"{indent}{_label(key)}: {scalar(key, value)}"]


def _robot(name: str, r: dict[str, Any]) -> list[str]:
    head = f"  {name}: on {r.get('storey', '?')}"
    if r.get("namespace"):
        head += f", namespace {r['namespace']}"
    lines = [head]
    topics = r.get("topics")
    if isinstance(topics, dict) and topics:
        lines.append("    topics: " + ", ".join(f"{t} ({skill})" for t, skill in topics.items()))
    if r.get("switches"):
        when = f", last {scalar('switched_ns', r['switched_ns'])}" if r.get("switched_ns") else ""
        lines.append(f"    storey switches: {r['switches']}{when}")
    if r.get("refused"):
        lines.append(f"    refused switches: {r['refused']}")
    rest = {
        k: v
        for k, v in r.items()
        if k not in ("storey", "namespace", "topics", "switches", "switched_ns", "refused")
    }
    for k, v in rest.items():
        lines += generic(k, v, "    ")
    return lines


def describe_status(status: dict[str, Any]) -> str:
    """The daemon's status as lines: a key a line, a map or cloud a line, a robot a block."""
    out: list[str] = []
    for key, value in status.items():
        if key == "maps" and isinstance(value, list):
            out.append(f"maps ({len(value)}):")
            out += [
                f"  {m.get('storey')}/{m.get('skill')} version {m.get('version')} "
                f"(revision {m.get('revision')})"
                for m in value
                if isinstance(m, dict)
            ]
        elif key == "points" and isinstance(value, list):
            if not value:
                out.append("points: none")
                continue
            out.append(f"points ({len(value)}):")
            out += [
                f"  {p.get('storey')}/{p.get('skill')} version {p.get('version')} "
                f"(revision {p.get('revision')}): {p.get('points', 0):,} points"
                for p in value
                if isinstance(p, dict)
            ]
        elif key == "robots" and isinstance(value, dict):
            out.append(f"robots ({len(value)}):" if value else "robots: none")
            for name, r in value.items():
                out += _robot(name, r) if isinstance(r, dict) else generic(name, r, "  ")
        elif key == "store" and isinstance(value, str):
            out.append(f"store: {value}")
        elif key == "sizes" and isinstance(value, dict):  # for leak hunts: a line, the list in --json
            out.append(f"sizes: {len(value)} containers of the writer (twin status --json lists them)")
        else:
            out += generic(key, value)
    return "\n".join(out)


def _element(e: dict[str, Any]) -> str:
    name = f"{e.get('name')!r} " if e.get("name") else ""
    text = f"{name}{e.get('class') or ''} <{e['iri']}>"
    if e.get("global_id"):
        text += f" GlobalId {e['global_id']}"
    seen = e.get("observed")
    if seen:
        text += f", observed by {seen['robot']} at {_iso_local(seen.get('at'))} (revision {seen['revision']})"
    return text


def _iso_local(at: Any) -> str:
    """An ISO time of the graph (``2026-11-24T23:20:01.123456Z``) in local time; other text as it is."""
    if not isinstance(at, str):
        return str(at)
    try:
        t = dt.datetime.fromisoformat(at.replace("Z", "+00:00"))
    except ValueError:
        return at
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.UTC)
    t = t.astimezone()
    return f"{t:%Y-%m-%d %H:%M:%S}.{t.microsecond // 1000:03d} {t:%Z}"


def _fusion(f: dict[str, Any], indent: str) -> list[str]:
    """What fusion knows of an element: sightings per robot, aliases, misses (anything else generic)."""
    lines: list[str] = []
    for robot, s in (f.get("sightings") or {}).items():
        times = "once" if s.get("count") == 1 else f"{s.get('count')} times"
        span = scalar("first_ns", s.get("first_ns"))
        if s.get("count", 0) > 1:
            span = f"first {span}, last {scalar('last_ns', s.get('last_ns'))}"
        lines.append(f"{indent}seen by {robot} {times} ({span})")
    if f.get("aliases"):
        lines.append(f"{indent}also reported as: {', '.join(f'<{a}>' for a in f['aliases'])}")
    for m in f.get("misses") or []:
        when = scalar("sense_ns", m.get("sense_ns"))
        lines.append(f"{indent}missed by {m.get('robot')} (a view that should have seen it) at {when}")
    for k, v in f.items():
        if k not in ("sightings", "aliases", "misses", "seen_ns"):
            lines += generic(k, v, indent)
    return lines


def describe_explain(answer: dict[str, Any]) -> str:
    """``twin explain``'s answer: the cell, then each element that fills it or lies near, with what fusion
    knows of it."""
    cell = answer["cell"]
    out = [
        f"{answer['storey']}/{answer['skill']} at ({answer['x']}, {answer['y']}), cell "
        f"({cell['col']}, {cell['row']}): {answer['state']} ({answer['value']})"
    ]
    sections = (
        ("occupied_by", "occupied by {}"),
        ("within_inflation_of", "within the inflation radius of {}"),
        ("near", "near ({distance_m} m), not drawn: {why_not}: {}"),
    )
    for key, form in sections:
        for e in answer.get(key, []):
            out.append(
                "  " + form.format(_element(e), distance_m=e.get("distance_m"), why_not=e.get("why_not"))
            )
            out += _fusion(e.get("fusion") or {}, "    ")
    known = {"ok", "storey", "skill", "x", "y", "cell", "value", "state", *(k for k, _ in sections)}
    for k, v in answer.items():
        if k not in known:
            out += generic(k, v, "  ")
    return "\n".join(out)
