"""Configuration: ``config/default.toml`` merged with an optional user file, into typed records.

Example::

    cfg = load_config(Path("site.toml"))     # or load_config() for the defaults
    skill = cfg.skill("lab-navigation")
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from twin.errors import ConfigError, SkillError
from twin.skills import SkillProfile, parse_skill

Right = Literal["create", "dynamic", "doors", "static", "zones"]
RIGHTS: tuple[Right, ...] = ("create", "dynamic", "doors", "static", "zones")
RosLayout = Literal["bridge", "rmw_zenoh"]
ZenohMode = Literal["peer", "client", "router"]
Identity = Literal["username", "certificate"]

DEFAULT_CONFIG = Path(__file__).resolve().parent / "default.toml"  # package data: installs with twin
KERNELS = ("manifold", "opencascade", "cgal", "cgal-simple", "hybrid-cgal-simple-opencascade")


@dataclass(frozen=True, slots=True)
class ImportConfig:
    kernels: tuple[str, ...]
    threads: int
    static_types: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class TlsConfig:
    """TLS on ``tls/...`` endpoints: this side's certificate and key, and the authority both trust.

    ``mutual`` makes a listener require client certificates (mTLS).
    """

    root_ca: Path | None = None
    certificate: Path | None = None
    private_key: Path | None = None
    mutual: bool = False
    verify_name: bool = True


@dataclass(frozen=True, slots=True)
class AuthConfig:
    """Zenoh user/password authentication: ``user`` and ``password_file`` to connect as someone,
    ``users_file`` (``name:password`` lines) to check who connects."""

    user: str | None = None
    password_file: Path | None = None
    users_file: Path | None = None


@dataclass(frozen=True, slots=True)
class AccessConfig:
    """Zenoh access control generated from the configured robots (see ``adapters.zenoh.access``)."""

    enabled: bool = False
    identity: Identity = "username"
    operators: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class RemoteStoreConfig:
    """A SPARQL 1.1 server holding the graph instead of the embedded store (``[store] url``).

    The endpoints are paths under ``url`` (``""``: ``url`` itself) or absolute URLs; the defaults are
    Oxigraph's (``oxigraph serve``). ``timeout_s`` bounds every socket operation of every request.
    """

    url: str
    query_endpoint: str = "query"
    update_endpoint: str = "update"
    graph_store_endpoint: str = "store"
    timeout_s: float = 30.0


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    """Where the daemon meets robots. ``prefix`` has ``{site}`` replaced (see :meth:`Config.key_prefix`)."""

    prefix: str = "twin/{site}"
    mode: ZenohMode = "peer"
    listen: tuple[str, ...] = ("tcp/127.0.0.1:7447",)
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    shared_memory: bool = False
    config_file: Path | None = None
    tls: TlsConfig = TlsConfig()
    auth: AuthConfig = AuthConfig()
    access: AccessConfig = AccessConfig()


@dataclass(frozen=True, slots=True)
class Limits:
    """Bounds on what one message may ask of the daemon."""

    payload_bytes: int = 1 << 20
    elements_per_observation: int = 256
    triangles_per_mesh: int = 200_000
    box_size_m: float = 50.0
    site_margin_m: float = 20.0
    sparql_timeout_s: float = 5.0
    sparql_result_bytes: int = 16 << 20
    full_map_interval_s: float = 0.2


DEFAULT_ROBOT_MAPS: tuple[tuple[str, str], ...] = (("map", "localization"), ("navigation_map", "navigation"))
"""A namespaced robot's topics when its table names none: AMCL reads ``map`` (its default
``map_topic``), so that carries the localization skill; the costmap's static layer is pointed at
``navigation_map`` (``map_topic: navigation_map``) for the navigation skill."""
RESERVED_TOPICS = ("storey",)
"""Topic names under a robot's namespace that the daemon uses for something else (``/<ns>/storey``)."""


@dataclass(frozen=True, slots=True)
class RobotConfig:
    """A configured robot: what it may change, and (with a ``namespace``) the ROS 2 maps it receives.

    ``maps`` pairs a topic name under the namespace with a skill, e.g. ``(("map", "localization"),
    ("navigation_map", "navigation"))``: each topic carries that skill's map of the robot's current
    ``storey`` (latched), and ``<topic>_updates`` its changed rectangles.
    """

    name: str
    rights: frozenset[Right]
    namespace: str | None = None
    maps: tuple[tuple[str, str], ...] = ()
    storey: str | None = None
    domain_id: int = 0
    ros: tuple[RosLayout, ...] = ("bridge", "rmw_zenoh")

    @property
    def skills(self) -> tuple[str, ...]:
        """The skills whose maps this robot receives, in topic order, each once."""
        return tuple(dict.fromkeys(skill for _, skill in self.maps))


@dataclass(frozen=True, slots=True)
class RerunConfig:
    record: bool = True
    directory: Path = Path("var/recordings")
    connect_url: str | None = None
    rotate_every_s: float = 0.0
    """Start a new file this often (0: never); each file replays on its own."""
    max_bytes: int = 0
    """Start a new file once the current one is this big (0: no limit)."""


@dataclass(frozen=True, slots=True)
class Config:
    site: str
    base_iri_template: str
    store_path: Path
    import_: ImportConfig
    margin_m: float
    maps_out: Path
    skills: Mapping[str, SkillProfile]
    zenoh: ZenohConfig = ZenohConfig()
    limits: Limits = Limits()
    default_rights: frozenset[Right] = frozenset({"create", "dynamic", "doors"})
    robots: Mapping[str, RobotConfig] = field(default_factory=dict)
    frame_id: str = "map"
    rerun: RerunConfig = RerunConfig()
    remote_store: RemoteStoreConfig | None = None
    """Set (``[store] url``): the graph is on a SPARQL 1.1 server, and ``store_path`` is unused."""
    store_flush_every_s: float = 60.0
    """``[store] flush_every_s``: how often the daemon flushes the embedded store's buffers."""

    def key_prefix(self, site: str | None = None) -> str:
        """The Zenoh key prefix of this site, e.g. ``twin/lab``."""
        return self.zenoh.prefix.replace("{site}", site or self.site).strip("/")

    def rights_of(self, robot: str) -> frozenset[Right]:
        """What ``robot`` may change: its own ``rights`` if configured, else ``[rights] default``."""
        configured = self.robots.get(robot)
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
    site = _get(raw, "site.name", str)
    if not _SITE.match(site):
        msg = f"Configuration 'site.name' must be 1-64 of [A-Za-z0-9_-], got {site!r}."
        raise ConfigError(msg)
    default_rights = _rights("rights.default", raw.get("rights", {}).get("default", list(_DEFAULT_RIGHTS)))
    return Config(
        site=site,
        base_iri_template=_get(raw, "site.base_iri", str),
        store_path=Path(_get(raw, "store.path", str)),
        remote_store=_remote_store(raw.get("store", {})),
        store_flush_every_s=_flush_every(raw.get("store", {})),
        import_=ImportConfig(kernels=tuple(kernels), threads=threads, static_types=tuple(static_types)),
        margin_m=margin,
        maps_out=Path(_get(raw, "maps.out", str)),
        skills=skills,
        zenoh=_zenoh(raw.get("zenoh", {})),
        limits=_limits(raw.get("limits", {})),
        default_rights=default_rights,
        robots=_robots(raw.get("robots", {}), default_rights, skills),
        frame_id=str(raw.get("ros", {}).get("frame_id", "map")),
        rerun=_rerun(raw.get("rerun", {})),
    )


_SITE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_ROBOT = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_DEFAULT_RIGHTS: tuple[Right, ...] = ("create", "dynamic", "doors")


def _table(raw: Any, name: str) -> Mapping[str, Any]:
    if not isinstance(raw, Mapping):
        msg = f"Configuration '{name}' must be a table, got {raw!r}."
        raise ConfigError(msg)
    return raw


def _unknown(table: Mapping[str, Any], name: str, known: set[str]) -> None:
    extra = sorted(set(table) - known)
    if extra:
        msg = f"Configuration '{name}' has an unknown key {extra[0]!r} (known: {', '.join(sorted(known))})."
        raise ConfigError(msg)


def _endpoints(value: Any, name: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(v, str) and "/" in v for v in value):
        msg = f"Configuration '{name}' must list endpoints such as \"tcp/127.0.0.1:7447\", got {value!r}."
        raise ConfigError(msg)
    return tuple(value)


def _flag(table: Mapping[str, Any], key: str, name: str, default: bool) -> bool:
    value = table.get(key, default)
    if not isinstance(value, bool):
        msg = f"Configuration '{name}.{key}' must be true or false, got {value!r}."
        raise ConfigError(msg)
    return value


def _zenoh(raw: Any) -> ZenohConfig:
    t = _table(raw, "zenoh")
    _unknown(
        t,
        "zenoh",
        {"prefix", "mode", "listen", "connect", "multicast_scouting", "shared_memory", "config_file"}
        | {"tls", "auth", "access"},
    )
    mode = t.get("mode", "peer")
    if mode not in ("peer", "client", "router"):
        msg = f"Configuration 'zenoh.mode' must be peer, client or router, got {mode!r}."
        raise ConfigError(msg)
    prefix = t.get("prefix", "twin/{site}")
    if not isinstance(prefix, str) or not prefix.strip("/") or any(c in prefix for c in "*$?#"):
        msg = f"Configuration 'zenoh.prefix' must be a key expression without wildcards, got {prefix!r}."
        raise ConfigError(msg)
    cfg_file = t.get("config_file")
    if cfg_file is not None and not isinstance(cfg_file, str):
        msg = f"Configuration 'zenoh.config_file' must be a path, got {cfg_file!r}."
        raise ConfigError(msg)
    return ZenohConfig(
        prefix=prefix,
        mode=mode,
        listen=_endpoints(t.get("listen", ["tcp/127.0.0.1:7447"]), "zenoh.listen"),
        connect=_endpoints(t.get("connect", []), "zenoh.connect"),
        multicast_scouting=_flag(t, "multicast_scouting", "zenoh", False),
        shared_memory=_flag(t, "shared_memory", "zenoh", False),
        config_file=Path(cfg_file) if cfg_file else None,
        tls=_tls(t.get("tls", {})),
        auth=_auth(t.get("auth", {})),
        access=_access(t.get("access", {})),
    )


def _path(table: Mapping[str, Any], key: str, name: str) -> Path | None:
    """An optional path setting; "" means none."""
    value = table.get(key, "")
    if not isinstance(value, str):
        msg = f"Configuration '{name}.{key}' must be a path, got {value!r}."
        raise ConfigError(msg)
    return Path(value) if value else None


def _tls(raw: Any) -> TlsConfig:
    t = _table(raw, "zenoh.tls")
    _unknown(t, "zenoh.tls", {"root_ca", "certificate", "private_key", "mutual", "verify_name"})
    tls = TlsConfig(
        root_ca=_path(t, "root_ca", "zenoh.tls"),
        certificate=_path(t, "certificate", "zenoh.tls"),
        private_key=_path(t, "private_key", "zenoh.tls"),
        mutual=_flag(t, "mutual", "zenoh.tls", False),
        verify_name=_flag(t, "verify_name", "zenoh.tls", True),
    )
    if (tls.certificate is None) != (tls.private_key is None):
        msg = "Configuration 'zenoh.tls' needs both 'certificate' and 'private_key', or neither."
        raise ConfigError(msg)
    return tls


def _auth(raw: Any) -> AuthConfig:
    t = _table(raw, "zenoh.auth")
    _unknown(t, "zenoh.auth", {"user", "password_file", "users_file"})
    user = t.get("user", "")
    if not isinstance(user, str):
        msg = f"Configuration 'zenoh.auth.user' must be a name, got {user!r}."
        raise ConfigError(msg)
    auth = AuthConfig(
        user=user or None,
        password_file=_path(t, "password_file", "zenoh.auth"),
        users_file=_path(t, "users_file", "zenoh.auth"),
    )
    if (auth.user is None) != (auth.password_file is None):
        msg = "Configuration 'zenoh.auth' needs both 'user' and 'password_file', or neither."
        raise ConfigError(msg)
    return auth


def _access(raw: Any) -> AccessConfig:
    t = _table(raw, "zenoh.access")
    _unknown(t, "zenoh.access", {"enabled", "identity", "operators"})
    identity = t.get("identity", "username")
    if identity not in ("username", "certificate"):
        msg = f"Configuration 'zenoh.access.identity' must be username or certificate, got {identity!r}."
        raise ConfigError(msg)
    operators = t.get("operators", [])
    if not isinstance(operators, list) or not all(isinstance(o, str) and _ROBOT.match(o) for o in operators):
        msg = f"Configuration 'zenoh.access.operators' must list names of [A-Za-z0-9_-], got {operators!r}."
        raise ConfigError(msg)
    return AccessConfig(
        enabled=_flag(t, "enabled", "zenoh.access", False), identity=identity, operators=tuple(operators)
    )


def _limits(raw: Any) -> Limits:
    t = _table(raw, "limits")
    known = set(Limits.__dataclass_fields__)
    _unknown(t, "limits", known)
    args: dict[str, Any] = {}
    for key, value in t.items():
        default = getattr(Limits(), key)
        kind = int if isinstance(default, int) else (int, float)
        if isinstance(value, bool) or not isinstance(value, kind) or not (0 < value < float("inf")):
            msg = f"Configuration 'limits.{key}' must be a positive number, got {value!r}."
            raise ConfigError(msg)
        args[key] = value if isinstance(default, int) else float(value)
    return Limits(**args)


def _remote_store(raw: Any) -> RemoteStoreConfig | None:
    t = _table(raw, "store")
    endpoints = ("query_endpoint", "update_endpoint", "graph_store_endpoint")
    _unknown(t, "store", {"path", "url", "timeout_s", "flush_every_s", *endpoints})
    url = t.get("url", "")
    if not isinstance(url, str) or (url and not re.match(r"^https?://[^/?#\s]+", url)):
        msg = f"Configuration 'store.url' must be \"\" or an http(s):// URL of a SPARQL server, got {url!r}."
        raise ConfigError(msg)
    if not url:
        return None
    timeout = t.get("timeout_s", 30.0)
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0 < timeout < float("inf"):
        msg = f"Configuration 'store.timeout_s' must be a positive number of seconds, got {timeout!r}."
        raise ConfigError(msg)
    fields = RemoteStoreConfig.__dataclass_fields__
    paths = {key: t.get(key, fields[key].default) for key in endpoints}
    for key, value in paths.items():
        if not isinstance(value, str):
            msg = f"Configuration 'store.{key}' must be a path under store.url or a URL, got {value!r}."
            raise ConfigError(msg)
    return RemoteStoreConfig(url=url, timeout_s=float(timeout), **paths)


def _flush_every(t: Any) -> float:
    value = t.get("flush_every_s", 60.0) if isinstance(t, dict) else 60.0
    if isinstance(value, bool) or not isinstance(value, int | float) or not 1.0 <= value <= 3600.0:
        msg = f"Configuration 'store.flush_every_s' must be seconds from 1 to 3600, got {value!r}."
        raise ConfigError(msg)
    return float(value)


def _rights(name: str, value: Any) -> frozenset[Right]:
    if not isinstance(value, list) or any(v not in RIGHTS for v in value):
        msg = f"Configuration '{name}' must list rights among {', '.join(RIGHTS)}, got {value!r}."
        raise ConfigError(msg)
    return frozenset(value)


def _robots(
    raw: Any, default_rights: frozenset[Right], skills: Mapping[str, SkillProfile]
) -> dict[str, RobotConfig]:
    robots: dict[str, RobotConfig] = {}
    for name, table in _table(raw, "robots").items():
        where = f"robots.{name}"
        if not _ROBOT.match(name):
            msg = f"Configuration '{where}': a robot name must be 1-64 of [A-Za-z0-9_-]."
            raise ConfigError(msg)
        t = _table(table, where)
        _unknown(t, where, {"namespace", "skill", "maps", "storey", "domain_id", "ros", "rights"})
        rights = _rights(f"{where}.rights", t["rights"]) if "rights" in t else default_rights
        ns = t.get("namespace")
        if ns is not None and (not isinstance(ns, str) or not _NAMESPACE.match(ns)):
            msg = (
                f"Configuration '{where}.namespace' must be a ROS namespace such as \"/robot1\", got {ns!r}."
            )
            raise ConfigError(msg)
        maps = _robot_maps(t, where, skills) if ns is not None or "skill" in t or "maps" in t else ()
        storey = t.get("storey")
        if ns is not None and (not isinstance(storey, str) or not storey):
            msg = (
                f"Configuration '{where}.storey': a robot with a namespace needs the key of the storey "
                f"it starts on, got {storey!r}."
            )
            raise ConfigError(msg)
        domain = t.get("domain_id", 0)
        if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
            msg = f"Configuration '{where}.domain_id' must be an integer in [0, 232], got {domain!r}."
            raise ConfigError(msg)
        ros = t.get("ros", ["bridge", "rmw_zenoh"])
        if not isinstance(ros, list) or not ros or any(v not in ("bridge", "rmw_zenoh") for v in ros):
            msg = f'Configuration \'{where}.ros\' must list "bridge" and/or "rmw_zenoh", got {ros!r}.'
            raise ConfigError(msg)
        robots[name] = RobotConfig(
            name=name,
            rights=rights,
            namespace=("/" + ns.strip("/")) if ns else None,
            maps=maps,
            storey=storey if ns is not None else None,
            domain_id=domain,
            ros=tuple(dict.fromkeys(ros)),
        )
    return robots


_NAMESPACE = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*/?$")
_TOPIC = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


def _robot_maps(
    t: Mapping[str, Any], where: str, skills: Mapping[str, SkillProfile]
) -> tuple[tuple[str, str], ...]:
    """``[robots.NAME.maps]`` (topic = skill), the old single ``skill`` (= ``{map = skill}``), or the
    defaults (:data:`DEFAULT_ROBOT_MAPS`)."""
    if "skill" in t and "maps" in t:
        msg = (
            f"Configuration '{where}' has both 'skill' and 'maps': 'skill = \"S\"' is the old form of "
            "'maps = { map = \"S\" }'; keep only 'maps'."
        )
        raise ConfigError(msg)
    if "skill" in t:
        raw: Any = {"map": t["skill"]}
        key = f"{where}.skill"
    elif "maps" in t:
        raw, key = t["maps"], f"{where}.maps"
    else:
        raw, key = dict(DEFAULT_ROBOT_MAPS), f"{where}.maps (default)"
    if not isinstance(raw, Mapping) or not raw:
        msg = (
            f"Configuration '{key}' must map topic names to skills, "
            f'e.g. {{ map = "localization" }}, got {raw!r}.'
        )
        raise ConfigError(msg)
    out: list[tuple[str, str]] = []
    for topic, skill in raw.items():
        if not isinstance(topic, str) or not _TOPIC.match(topic):
            msg = (
                f"Configuration '{key}': topic {topic!r} must be a relative ROS topic name such as "
                '"map" or "nav/map" (it goes under the robot\'s namespace).'
            )
            raise ConfigError(msg)
        if topic in RESERVED_TOPICS or topic.endswith("_updates"):
            msg = (
                f"Configuration '{key}': topic {topic!r} is taken (the daemon uses '/<ns>/storey' and "
                "'<topic>_updates' itself)."
            )
            raise ConfigError(msg)
        if not isinstance(skill, str) or skill not in skills:
            known = ", ".join(sorted(skills))
            msg = (
                f"Configuration '{key}': topic {topic!r} names unknown skill {skill!r}; configured: {known}."
            )
            raise ConfigError(msg)
        out.append((topic, skill))
    return tuple(out)


def _rerun(raw: Any) -> RerunConfig:
    t = _table(raw, "rerun")
    _unknown(t, "rerun", {"record", "directory", "connect_url", "rotate_every_s", "max_bytes"})
    rotate, max_bytes = t.get("rotate_every_s", 0), t.get("max_bytes", 0)
    if isinstance(rotate, bool) or not isinstance(rotate, int | float) or not 0 <= rotate <= 7 * 86400:
        msg = (
            f"Configuration 'rerun.rotate_every_s' must be seconds from 0 (never) to a week, got {rotate!r}."
        )
        raise ConfigError(msg)
    if (
        isinstance(max_bytes, bool)
        or not isinstance(max_bytes, int)
        or not (max_bytes == 0 or max_bytes >= 2**20)
    ):
        msg = f"Configuration 'rerun.max_bytes' must be 0 (no limit) or at least 1048576, got {max_bytes!r}."
        raise ConfigError(msg)
    directory = t.get("directory", "var/recordings")
    url = t.get("connect_url", "")
    if not isinstance(directory, str) or not isinstance(url, str):
        msg = "Configuration 'rerun.directory' and 'rerun.connect_url' must be strings."
        raise ConfigError(msg)
    return RerunConfig(
        record=_flag(t, "record", "rerun", True),
        directory=Path(directory),
        connect_url=url or None,
        rotate_every_s=float(rotate),
        max_bytes=max_bytes,
    )
