"""Configuration: ``config/default.toml`` merged with an optional user file, into typed records.

Example::

    cfg = load_config(Path("site.toml"))     # or load_config() for the defaults
    skill = cfg.skill("lab-navigation")
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.errors import ConfigError, SkillError
from twin.skills import SkillProfile, parse_skill

DEFAULT_CONFIG = Path(__file__).resolve().parent / "default.toml"  # package data: installs with twin
KERNELS = ("manifold", "opencascade", "cgal", "cgal-simple", "hybrid-cgal-simple-opencascade")


@dataclass(frozen=True, slots=True)
class ImportConfig:
    kernels: tuple[str, ...]
    threads: int
    static_types: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Config:
    site: str
    base_iri_template: str
    store_path: Path
    import_: ImportConfig
    margin_m: float
    maps_out: Path
    skills: Mapping[str, SkillProfile]

    def base_iri(self, site: str | None = None) -> str:
        return self.base_iri_template.replace("{site}", site or self.site)

    def skill(self, name: str) -> SkillProfile:
        try:
            return self.skills[name]
        except KeyError:
            known = ", ".join(sorted(self.skills)) or "none"
            msg = f"Unknown skill {name!r}; configured skills: {known}."
            raise SkillError(msg) from None


def _read(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        msg = f"No configuration file at {path}."
        raise ConfigError(msg) from None
    except OSError as err:
        msg = f"Cannot read the configuration file {path}: {err.strerror or err}."
        raise ConfigError(msg) from err
    except tomllib.TOMLDecodeError as err:
        msg = f"Configuration file {path} is not valid TOML: {err}."
        raise ConfigError(msg) from err


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in over.items():
        if key == "skills" and isinstance(value, Mapping):
            out[key] = {**out.get(key, {}), **value}  # a skill table replaces that skill whole
        elif isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _get(table: Mapping[str, Any], dotted: str, kind: type | tuple[type, ...]) -> Any:
    node: Any = table
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            msg = f"Configuration lacks '{dotted}'."
            raise ConfigError(msg)
        node = node[part]
    if isinstance(node, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
        msg = f"Configuration '{dotted}' has the wrong type: {node!r}."
        raise ConfigError(msg)
    if not isinstance(node, kind):
        msg = f"Configuration '{dotted}' has the wrong type: {node!r}."
        raise ConfigError(msg)
    return node


def load_config(path: Path | None = None) -> Config:
    """Load the defaults, then ``path`` on top of them (if given)."""
    raw = _read(DEFAULT_CONFIG)
    if path is not None:
        raw = _merge(raw, _read(Path(path)))
    skills_raw = _get(raw, "skills", dict)
    try:
        skills = {name: parse_skill(name, table) for name, table in skills_raw.items()}
    except SkillError as err:
        msg = f"In the configuration: {err}"
        raise ConfigError(msg) from err
    threads = _get(raw, "import.threads", int)
    if threads < 1:
        msg = f"Configuration 'import.threads' must be >= 1, got {threads}."
        raise ConfigError(msg)
    kernels = _get(raw, "import.kernels", list)
    if not kernels or any(k not in KERNELS for k in kernels):
        msg = f"Configuration 'import.kernels' must list kernels among {', '.join(KERNELS)}, got {kernels!r}."
        raise ConfigError(msg)
    static_types = _get(raw, "import.static_types", list)
    if any(not isinstance(t, str) or not t.startswith("Ifc") for t in static_types):
        msg = f"Configuration 'import.static_types' must list IFC class names, got {static_types!r}."
        raise ConfigError(msg)
    margin = float(_get(raw, "maps.margin_m", (int, float)))
    if not 0.0 <= margin <= 100.0:  # also false for NaN
        msg = f"Configuration 'maps.margin_m' must be between 0 and 100 metres, got {margin!r}."
        raise ConfigError(msg)
    return Config(
        site=_get(raw, "site.name", str),
        base_iri_template=_get(raw, "site.base_iri", str),
        store_path=Path(_get(raw, "store.path", str)),
        import_=ImportConfig(kernels=tuple(kernels), threads=threads, static_types=tuple(static_types)),
        margin_m=margin,
        maps_out=Path(_get(raw, "maps.out", str)),
        skills=skills,
    )
