"""Loading: ``config/default.toml`` merged with an optional user file, validated table by table into
a :class:`Config`.

The core validates its own tables. The adapters' tables (``[zenoh]``, ``[rerun]``, ``[ros]``, the
remote store's keys in ``[store]``, the ROS keys of each ``[robots.NAME]``) are
:class:`~twin.config.base.ConfigSection` schemas that the composition root passes as ``sections``:
then the whole file is checked at once, and a table or key that nobody knows is an error. Without
``sections`` (the core's own tests and tools) the adapters' tables and keys are kept as they were
written and parsed when first asked for (:meth:`Config.section`, :meth:`Config.each`).
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, TypeVar, cast

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, WithJsonSchema, create_model

from twin.config.base import ConfigSection, ConfigTable
from twin.config.fusion import FusionRules, FusionTable
from twin.config.messages import config_error
from twin.config.robots import RobotConfig, RobotName, RobotTable
from twin.config.routes import RouteProfile, RoutesTable, check_routes, parse_routes
from twin.config.sources import SourceConfig, SourceTable
from twin.config.tables import (
    DEFAULT_MAX_POINTS,
    ImportConfig,
    Limits,
    MapsTable,
    Right,
    RightsTable,
    SiteTable,
    StoreTable,
)
from twin.errors import ConfigError, RouteError, SkillError
from twin.selection.skills import SkillProfile, parse_skill

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "default.toml"  # package data: installs with twin
S = TypeVar("S", bound=ConfigSection)
_ROLE = re.compile(r":\w+:`~?([^`]+)`")

CORE_TABLES: dict[str, type[ConfigTable]] = {
    "site": SiteTable,
    "store": StoreTable,
    "import": ImportConfig,
    "maps": MapsTable,
    "limits": Limits,
    "rights": RightsTable,
    "fusion": FusionTable,
}
"""The core's tables with one schema each; ``[skills.NAME]`` and :data:`NAMED_TABLES` hold many."""
NAMED_TABLES: dict[str, type[ConfigTable]] = {"robots": RobotTable, "sources": SourceTable}
"""The core's tables of one table per name (``[robots.NAME]``, ``[sources.NAME]``): the core's keys
of each (rights, storey, kind); adapters add theirs (``ConfigSection.each``). Without sections, the
other keys are left to the adapters (:meth:`Config.each`)."""


@dataclass(frozen=True, slots=True)
class Config:
    """The configuration the core uses, and the adapters' sections (:meth:`section`)."""

    site: str
    base_iri_template: str
    store_path: Path
    import_: ImportConfig
    margin_m: float
    maps_out: Path
    skills: Mapping[str, SkillProfile]
    """The map skills; ``kind = "routes"`` skills are in :attr:`routes`."""
    limits: Limits = field(default_factory=Limits)
    default_rights: frozenset[Right] = frozenset({"create", "dynamic", "doors"})
    robots: Mapping[str, RobotConfig] = field(default_factory=dict)
    sources: Mapping[str, SourceConfig] = field(default_factory=dict)
    """``[sources.NAME]``: the building's systems that report to the twin (Open-RMF doors, obstacles)."""
    store_flush_every_s: float = 60.0
    """``[store] flush_every_s``: how often the daemon flushes the embedded store's buffers."""
    max_points_per_storey: int = DEFAULT_MAX_POINTS
    """``[maps] max_points_per_storey``: the largest points cloud of a storey built without --force."""
    site_set: bool = False
    """True when the configuration file sets ``site.name``; otherwise ``site`` is the packaged default
    (``lab``) and commands name the site after the model file, the store or the running daemon."""
    store_snapshot: bool = True
    """``[store] snapshot``: keep the daemon's derived state (scene, maps) in ``<store>.snapshot``."""
    store_snapshot_every_s: float = 300.0
    """``[store] snapshot_every_s``: how often the daemon rewrites it while anything changes."""
    routes: Mapping[str, RouteProfile] = field(default_factory=dict)
    """``[skills.NAME]`` of ``kind = "routes"``: fleets' route graphs (:mod:`twin.routes`)."""
    fusion: FusionRules = field(default_factory=FusionRules)
    """``[fusion]``: association, confirmation, absence and sense time (many robots, one twin)."""
    tables: Mapping[str, Any] = field(default_factory=dict, repr=False)
    """The merged file as written (defaults under the user's file)."""
    sections: Mapping[type[ConfigSection], ConfigSection] = field(default_factory=dict, repr=False)
    """The adapters' sections validated at load time."""
    named_sections: Mapping[type[ConfigSection], Mapping[str, ConfigSection]] = field(
        default_factory=dict, repr=False
    )
    """The adapters' ``each`` sections validated at load time, by the name of their table."""

    def section(self, kind: type[S]) -> S:
        """The adapter table ``kind`` (e.g. ``ZenohSettings``): validated at load time if the loader
        was given it, else parsed now from the file (a :class:`ConfigError` naming the key if bad;
        in a table shared with the core, keys that ``kind`` does not know are left to their owners)."""
        if kind.each:
            msg = f"{kind.__name__} holds keys of every [{kind.table}.NAME]: read it with Config.each"
            raise TypeError(msg)
        found = self.sections.get(kind)
        if isinstance(found, kind):
            return found
        alone = create_model("SectionFile", **{kind.table: (kind, Field(default_factory=kind))})  # type: ignore[call-overload]
        table = self.tables.get(kind.table, {})
        if kind.table in CORE_TABLES:  # other sections' keys are theirs
            table = _owned(kind, table)
        try:
            checked = alone.model_validate({kind.table: table}, context={"skills": set(self.skills)})
        except ValidationError as err:
            raise config_error(err, alone) from None
        section: S = getattr(checked, kind.table)
        return section

    def each(self, kind: type[S]) -> Mapping[str, S]:
        """The keys ``kind`` (an ``each`` section, e.g. a robot's ROS keys) of every
        ``[<kind.table>.NAME]``, by name: validated at load time if the loader was given ``kind``,
        else parsed now (a :class:`ConfigError` naming the table and key if bad; keys that ``kind``
        does not know are left to their owners). So a key that no table knows (a typo) is refused
        only when the loader is given every section, as the ``twin`` command's loader is; loaded
        without sections, it is ignored."""
        found = self.named_sections.get(kind)
        if found is not None:
            return cast(Mapping[str, S], found)
        alone = create_model("SectionFile", **{kind.table: (dict[str, kind], Field(default_factory=dict))})  # type: ignore[call-overload,valid-type]
        tables = self.tables.get(kind.table, {})
        if isinstance(tables, Mapping):
            tables = {name: _owned(kind, table) for name, table in tables.items()}
        try:
            checked = alone.model_validate({kind.table: tables}, context={"skills": set(self.skills)})
        except ValidationError as err:
            raise config_error(err, alone) from None
        named: dict[str, S] = getattr(checked, kind.table)
        return named

    def rights_of(self, robot: str) -> frozenset[Right]:
        """What ``robot`` (or source) may change: its own ``rights`` if configured, else
        ``[rights] default``."""
        configured = self.robots.get(robot)
        if configured is None and robot in self.sources:
            return self.sources[robot].rights
        return configured.rights if configured is not None else self.default_rights

    def base_iri(self, site: str | None = None) -> str:
        return self.base_iri_template.replace("{site}", site or self.site)

    def skill(self, name: str) -> SkillProfile:
        try:
            return self.skills[name]
        except KeyError:
            known = ", ".join(sorted(self.skills)) or "none"
            msg = f"Unknown skill {name!r}; configured skills: {known}."
            raise SkillError(msg) from None


def load_config(
    path: Path | None = None,
    *,
    sections: Sequence[type[ConfigSection]] | None = None,
    defaults: Path = DEFAULT_CONFIG,
) -> Config:
    """Load ``defaults`` (``config/default.toml``), then ``path`` on top of them (if given), validated.

    ``sections``: the adapters' tables to validate too; given (even empty), a table or key that
    neither the core nor a section knows is an error.
    """
    raw = _read(defaults)
    site_set = False
    if path is not None:
        own = _read(Path(path))
        site_table = own.get("site")
        site_set = isinstance(site_table, Mapping) and "name" in site_table
        raw = _merge(raw, own)
    raw = _robot_defaults(raw)
    skills, routes = _skills(raw.get("skills", {}))
    model = file_model(sections or (), strict=sections is not None)
    data = raw if sections is not None else _core_keys(raw)
    context = {"skills": set(skills)}
    try:
        checked: Any = model.model_validate(data, context=context)
    except ValidationError as err:
        raise config_error(err, model) from None
    default_rights = frozenset(checked.rights.default)
    clash = sorted(set(checked.robots) & set(checked.sources))
    if clash:
        msg = f"Configuration [sources.{clash[0]}]: a robot has that name too; give the source its own."
        raise ConfigError(msg)
    return Config(
        site=checked.site.name,
        site_set=site_set,
        base_iri_template=checked.site.base_iri,
        store_path=checked.store.path,
        import_=checked.import_,
        margin_m=checked.maps.margin_m,
        max_points_per_storey=checked.maps.max_points_per_storey,
        maps_out=checked.maps.out,
        skills=skills,
        routes=routes,
        limits=checked.limits,
        default_rights=default_rights,
        robots={name: table.record(name, default_rights) for name, table in checked.robots.items()},
        sources={name: table.record(name) for name, table in checked.sources.items()},
        store_flush_every_s=checked.store.flush_every_s,
        store_snapshot=checked.store.snapshot,
        store_snapshot_every_s=checked.store.snapshot_every_s,
        fusion=checked.fusion.rules(),
        tables=raw,
        sections={
            s: s.model_validate(_section_keys(s, raw.get(s.table, {}))) for s in sections or () if not s.each
        },
        named_sections={s: _each(s, raw.get(s.table, {}), context) for s in sections or () if s.each},
    )


def file_model(sections: Sequence[type[ConfigSection]] = (), *, strict: bool = True) -> type[BaseModel]:
    """The schema of a whole configuration file: the core's tables and ``sections``; a table that a
    section shares with the core (``[store]``, each ``[robots.NAME]``) accepts the keys of both."""
    tables: dict[str, list[type[ConfigTable]]] = {name: [model] for name, model in CORE_TABLES.items()}
    named: dict[str, list[type[ConfigTable]]] = {name: [model] for name, model in NAMED_TABLES.items()}
    for section in sections:
        (named if section.each else tables).setdefault(section.table, []).append(section)
    fields: dict[str, Any] = {}
    for name, owners in tables.items():
        model = _merged(name, owners)
        fields[f"{name}_" if name == "import" else name] = (model, Field(default_factory=model, alias=name))
    fields["skills"] = (
        dict[str, Annotated[dict[str, Any], WithJsonSchema(_skill_schema())]],
        Field(default_factory=dict, description="Skill profiles: [skills.NAME] (docs/skills.md)."),
    )
    for name, owners in named.items():
        fields[name] = (dict[RobotName, _merged(name, owners)], Field(default_factory=dict))  # type: ignore[misc]
    return create_model(
        "BuildingTwinConfig",
        __config__=ConfigDict(extra="forbid" if strict else "ignore", frozen=True, populate_by_name=True),
        **fields,
    )


def config_schema(sections: Sequence[type[ConfigSection]] = ()) -> dict[str, Any]:
    """The JSON Schema of ``config/*.toml`` (for editors: Taplo, Even Better TOML)."""
    schema = _plain(file_model(sections).model_json_schema(by_alias=True))
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "building-twin configuration",
        "description": "config/default.toml and the files given with 'twin --config FILE'.",
        **{k: v for k, v in schema.items() if k != "title"},
    }


def _skill_schema() -> dict[str, Any]:
    """A skill table's keys for editors, from :class:`SkillProfile`'s fields (checked by
    :func:`~twin.selection.skills.parse_skill`, which also refuses keys that do not belong to the kind)."""
    schema = TypeAdapter(SkillProfile).json_schema()
    properties = {k: v for k, v in schema["properties"].items() if k != "name"}
    properties["sparql"] = {"type": "string", "description": "A group graph pattern binding ?element."}
    routes = RoutesTable.model_json_schema()
    for key, value in routes["properties"].items():  # kind = "routes" (twin.config.routes)
        if key not in properties:
            properties[key] = _inline(value, routes.get("$defs", {}))
    properties["kind"] = {**properties["kind"], "enum": [*properties["kind"]["enum"], "routes"]}
    return {
        "type": "object",
        "properties": properties,
        "required": ["kind"],
        "additionalProperties": False,
        "description": schema.get("description", ""),
    }


def _inline(node: Any, defs: Mapping[str, Any]) -> Any:
    """``node`` with its ``$ref``s to ``defs`` replaced by what they name."""
    if isinstance(node, dict):
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.startswith("#/$defs/"):
            return _inline(defs[ref.removeprefix("#/$defs/")], defs)
        return {k: _inline(v, defs) for k, v in node.items()}
    if isinstance(node, list):
        return [_inline(v, defs) for v in node]
    return node


def _plain(node: Any) -> Any:
    """Descriptions as editors show them: ``:mod:`x``` and ````x```` -> ```x```."""
    if isinstance(node, dict):
        return {
            k: _ROLE.sub(r"`\1`", v.replace("``", "`"))
            if isinstance(v, str) and k == "description"
            else _plain(v)
            for k, v in node.items()
        }
    if isinstance(node, list):
        return [_plain(v) for v in node]
    return node


def _merged(name: str, owners: Sequence[type[ConfigTable]]) -> type[ConfigTable]:
    """One table's schema from its owners' (the core's first: a key both declare is described by it)."""
    if len(owners) == 1:
        return owners[0]
    return cast(
        type[ConfigTable],
        create_model(f"{name.title()}File", __base__=tuple(owners), __doc__=owners[0].__doc__),
    )


def _each(kind: type[ConfigSection], tables: Mapping[str, Any], context: Any) -> dict[str, ConfigSection]:
    """An ``each`` section's keys of every named table (already checked with the whole file)."""
    return {name: kind.model_validate(_owned(kind, table), context=context) for name, table in tables.items()}


def _core_keys(raw: Mapping[str, Any]) -> dict[str, Any]:
    """The file without the keys that sections add to the core's tables (checked when asked for)."""
    out = dict(raw)
    for name, model in CORE_TABLES.items():
        if getattr(model, "extended_by_sections", False) and name in raw:
            out[name] = _owned(model, raw[name])
    for name, model in NAMED_TABLES.items():
        tables = raw.get(name)
        if isinstance(tables, Mapping):
            out[name] = {n: _owned(model, table) for n, table in tables.items()}
    return out


def _section_keys(kind: type[ConfigSection], table: Any) -> Any:
    """A section's keys of its table (all of them unless it shares the table with the core)."""
    return _owned(kind, table) if kind.table in CORE_TABLES else table


def _owned(model: type[ConfigTable], table: Any) -> Any:
    """The keys of ``table`` that ``model`` declares (``table`` as it is if not a table)."""
    if not isinstance(table, Mapping):
        return table
    return {k: v for k, v in table.items() if k in model.model_fields}


def _skills(raw: Any) -> tuple[dict[str, SkillProfile], dict[str, RouteProfile]]:
    """The map skills and the routes skills (``kind = "routes"``, checked against the map skills)."""
    if not isinstance(raw, Mapping):
        msg = f"Configuration [skills]: expected a table of skill profiles, got {raw!r}."
        raise ConfigError(msg)
    is_routes = {
        name: isinstance(table, Mapping) and table.get("kind") == "routes" for name, table in raw.items()
    }
    try:
        skills = {name: parse_skill(name, table) for name, table in raw.items() if not is_routes[name]}
    except SkillError as err:
        msg = f"Configuration [skills]: {err}"
        raise ConfigError(msg) from err
    routes = {name: parse_routes(name, table) for name, table in raw.items() if is_routes[name]}
    for profile in routes.values():
        try:
            check_routes(profile, skills)
        except RouteError as err:
            msg = f"Configuration [skills.{profile.name}]: {err}"
            raise ConfigError(msg) from err
    return skills, routes


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


def _robot_defaults(raw: dict[str, Any]) -> dict[str, Any]:
    """``[robot_defaults]``: keys (and tables, such as ``detections``) that every ``[robots.NAME]`` takes
    unless it sets them itself (tables merged key by key), so that a fleet of alike robots needs its
    detections settings once. It names no robot of its own."""
    defaults = raw.get("robot_defaults")
    if defaults is None:
        return raw
    if not isinstance(defaults, Mapping):
        msg = f"Configuration [robot_defaults]: expected a table of [robots.NAME] keys, got {defaults!r}."
        raise ConfigError(msg)
    out = {key: value for key, value in raw.items() if key != "robot_defaults"}
    robots = raw.get("robots", {})
    if isinstance(robots, Mapping):
        out["robots"] = {
            name: _merge(dict(defaults), table) if isinstance(table, Mapping) else table
            for name, table in robots.items()
        }
    return out


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
