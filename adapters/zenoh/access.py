"""Zenoh access control for a site: who may write what, from the configured robots and sources.

The daemon (or the router robots connect to) enforces it on its links; robots are told apart by the
name they authenticate with: their zenoh user name (``identity = "username"``, user/password
authentication) or the common name of their TLS client certificate (``identity = "certificate"``,
mutual TLS). A link that authenticates as nobody listed gets nothing (default deny).

- every robot: read maps, map updates, points skills' clouds, status, SPARQL and the skill list, and
  the ROS 2 map and ``points_map`` topics of the configured robots; put ``observations/<its name>``,
  query ``observe/<its name>``, put and query ``robots/<its name>/storey`` and publish its own ROS
  ``/<ns>/storey`` topic, nothing else;
- operators (``[zenoh.access] operators``): everything under the site's prefix (skills too), for
  people and for routers or daemons that relay;
- nobody but the daemon publishes maps: a robot's put on ``map/**`` (or ``points/**``, or a robot's map
  topics) is dropped at the daemon.

Example::

    acl = access_control(SiteKeys("twin/lab"), robots=["robot1"], identity="username")
    conf.insert_json5("access_control", json.dumps(acl))
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import zenoh

from adapters.ros.rmw_zenoh import ADMIN_SPACE, RosTopic, resolve_name
from adapters.ros.settings import RosRobot, RosSource, ros_robots, ros_sources
from adapters.zenoh.errors import TransportError
from adapters.zenoh.keys import SiteKeys, check_chunk
from adapters.zenoh.ros_maps import STOREY_TOPIC
from adapters.zenoh.ros_points import points_topic
from adapters.zenoh.settings import Identity, ZenohSettings
from twin.config import Config

# zenoh's ACL message kinds (zenoh-config AclMessage)
READ = ["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"]
ALL = [
    "put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
    "liveliness_token", "liveliness_query", "declare_liveliness_subscriber",
]  # fmt: skip
ADV = "@adv/**"  # zenoh-ext's advanced publishers and subscribers (latching, detection) live under <key>/@adv


def _with_adv(keys: Iterable[str]) -> list[str]:
    """``keys`` and their advanced-pub/sub sub-keys (``**`` never matches a chunk starting with ``@``)."""
    out: list[str] = []
    for key in keys:
        out += [key, f"{key}/{ADV}"]
    return out


def ros_map_keys(robots: Iterable[RosRobot]) -> list[str]:
    """The key expressions of the configured robots' ROS 2 map topics (and their ``_updates``), both
    layouts."""
    keys: list[str] = []
    for robot in robots:
        if robot.namespace is None:
            continue
        for topic_name, _ in robot.maps:
            for name in (topic_name, f"{topic_name}_updates"):
                keys += _ros_keys(robot, name)
    return keys


def ros_points_keys(cfg: Config) -> list[str]:
    """The key expressions of the configured robots' ROS 2 ``points_map`` topics (one per points skill,
    :mod:`adapters.zenoh.ros_points`), both layouts."""
    skills = sorted(name for name, skill in cfg.skills.items() if skill.kind == "points")
    keys: list[str] = []
    for robot in ros_robots(cfg).values():
        if robot.namespace is not None:
            for skill in skills:
                keys += _ros_keys(robot, points_topic(skill, several=len(skills) > 1))
    return keys


def ros_storey_keys(robot: RosRobot) -> list[str]:
    """The keys of the robot's ``/<ns>/storey`` topic (``std_msgs/String``), which only it publishes."""
    return _ros_keys(robot, STOREY_TOPIC) if robot.namespace is not None else []


def ros_report_keys(robot: RosRobot) -> list[str]:
    """The keys of the robot's detections, ``tf`` and ``tf_static`` topics, which only it publishes."""
    d = robot.detections
    if d is None or robot.namespace is None:
        return []
    return [key for name in (d.topic, d.tf, d.tf_static) for key in _ros_keys(robot, name)]


def ros_diagnostics_keys(cfg: Config) -> list[str]:
    """The keys of the ``/<ns>/diagnostics`` topics the daemon publishes (robots and sources that ask)."""
    keys: list[str] = []
    for robot in ros_robots(cfg).values():
        if robot.namespace is not None and robot.detections is not None and robot.detections.diagnostics:
            keys += _ros_keys(robot, "diagnostics")
    for source in ros_sources(cfg).values():
        if source.diagnostics:
            keys += _topic_keys(source.domain_id, source.namespace, "diagnostics", source.ros)
    return keys


def ros_source_keys(source: RosSource) -> list[str]:
    """The keys of a ``[sources.NAME]`` topic (door states, obstacles), which only that source publishes."""
    return _topic_keys(source.domain_id, source.namespace, source.topic, source.ros)


def _ros_keys(robot: RosRobot, name: str) -> list[str]:
    assert robot.namespace is not None
    return _topic_keys(robot.domain_id, robot.namespace, name, robot.ros)


def _topic_keys(domain_id: int, namespace: str, name: str, layouts: Sequence[str]) -> list[str]:
    topic = RosTopic(domain_id, *resolve_name(namespace, name), "nav_msgs/msg/OccupancyGrid")
    keys: list[str] = []
    if "bridge" in layouts:
        keys.append(topic.bridge_key)
    if "rmw_zenoh" in layouts:
        keys.append(f"{domain_id}/{topic.fqn.strip('/')}/**")
    return keys


def access_control(
    keys: SiteKeys,
    robots: Sequence[str],
    *,
    identity: Identity = "username",
    operators: Sequence[str] = (),
    ros_keys: Sequence[str] = (),
    robot_keys: Mapping[str, Sequence[str]] | None = None,
) -> dict[str, Any]:
    """The ``access_control`` section of a zenoh configuration for one site (see the module doc).

    ``robot_keys``: more keys a robot publishes on (its ROS ``/<ns>/storey`` topic), by robot name.
    """
    names = sorted({check_chunk(r, "Robot name") for r in robots})
    ops = sorted({check_chunk(o, "Operator name") for o in operators})
    if not names and not ops:
        msg = "Access control needs at least one robot ([robots.NAME]) or operator to let in."
        raise TransportError(msg)
    maps = _with_adv([keys.maps, keys.all_map_updates, keys.points, *ros_keys])
    reads = [*maps, keys.status, keys.sparql, keys.explain, keys.skills_listing, keys.daemon]
    rules: list[dict[str, Any]] = [
        {"id": "read", "permission": "allow", "flows": ["ingress"], "messages": READ, "key_exprs": reads},
        {   # the advanced subscribers' own detection tokens, and the ROS graph's liveliness tokens
            "id": "tokens",
            "permission": "allow",
            "flows": ["ingress"],
            "messages": ["liveliness_token"],
            "key_exprs": [*_with_adv([keys.maps, keys.points, *ros_keys]), f"{ADMIN_SPACE}/**"],
        },
        {
            "id": "ros-graph",
            "permission": "allow",
            "flows": ["ingress"],
            "messages": ["declare_liveliness_subscriber", "liveliness_query"],
            "key_exprs": [f"{ADMIN_SPACE}/**"],
        },
        {   # what the daemon sends: maps, updates, replies, its declarations
            "id": "from-daemon",
            "permission": "allow",
            "flows": ["egress"],
            "messages": ALL,
            "key_exprs": [*_with_adv([keys.everything, *ros_keys]), f"{ADMIN_SPACE}/**"],
        },
        {"id": "operate", "permission": "allow", "flows": ["ingress"], "messages": ALL,
         "key_exprs": _with_adv([keys.everything])},
        {   # deny wins over allow: not even an operator publishes (or answers for) a map
            "id": "no-forged-maps",
            "permission": "deny",
            "flows": ["ingress"],
            "messages": ["put", "delete", "declare_queryable", "reply"],
            "key_exprs": maps,
        },
    ]  # fmt: skip
    subject_key = "usernames" if identity == "username" else "cert_common_names"
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for name in names:
        rules.append(
            {
                "id": f"write-{name}",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put", "query"],
                "key_exprs": [keys.observations(name), keys.observe(name), keys.robot_storey(name)],
            }
        )
        own = ["read", "tokens", "ros-graph", "from-daemon", f"write-{name}"]
        if robot_keys and robot_keys.get(name):
            rules.append(
                {   # its ROS /<ns>/storey topic, latched or not (the publisher's @adv cache answers)
                    "id": f"publish-{name}",
                    "permission": "allow",
                    "flows": ["ingress"],
                    "messages": ["put", "declare_queryable", "reply", "liveliness_token"],
                    "key_exprs": _with_adv(robot_keys[name]),
                }
            )  # fmt: skip
            own.append(f"publish-{name}")
        subjects.append({"id": f"robot-{name}", subject_key: [name]})
        policies.append({"rules": [*own, "no-forged-maps"], "subjects": [f"robot-{name}"]})
    for name in ops:
        subjects.append({"id": f"operator-{name}", subject_key: [name]})
        policies.append(
            {
                "rules": ["read", "tokens", "ros-graph", "from-daemon", "operate", "no-forged-maps"],
                "subjects": [f"operator-{name}"],
            }
        )
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def site_access_control(cfg: Config, keys: SiteKeys, *, enforce: bool = False) -> dict[str, Any] | None:
    """The daemon's (or a router's) ``access_control`` from ``[zenoh.access]``, or None when off
    (``enforce``: on whatever ``enabled`` says, as ``twin router --acl`` asks).

    Checks that robots can be told apart: a users file for ``identity = "username"``, mutual TLS
    for ``identity = "certificate"``.
    """
    z = cfg.section(ZenohSettings)
    access = z.access
    if not access.enabled and not enforce:
        return None
    if access.identity == "username" and z.auth.users_file is None:
        msg = (
            "Access control by user name needs a users file of name:password lines "
            "(zenoh.auth.users_file): without it nobody can authenticate."
        )
        raise TransportError(msg)
    if access.identity == "certificate" and not (z.tls.mutual and z.tls.certificate and z.tls.root_ca):
        msg = (
            "Access control by certificate needs mutual TLS: zenoh.tls.mutual = true with root_ca, "
            "certificate and private_key, and tls/... listen endpoints."
        )
        raise TransportError(msg)
    return site_acl(cfg, keys)


def site_acl(cfg: Config, keys: SiteKeys, *, identity: Identity | None = None) -> dict[str, Any]:
    """The ``access_control`` section for the configured robots, ``[sources.NAME]`` and operators: what
    the daemon and ``twin router --acl`` enforce (:func:`site_access_control`) and ``twin acl`` prints,
    from this one function. ``identity``: how robots are known (default: ``[zenoh.access] identity``).
    Checks no authentication settings (a zenohd config has its own)."""
    access = cfg.section(ZenohSettings).access
    robots, sources = ros_robots(cfg), ros_sources(cfg)
    robot_keys = {name: ros_storey_keys(robot) + ros_report_keys(robot) for name, robot in robots.items()}
    robot_keys |= {name: ros_source_keys(source) for name, source in sources.items()}  # identities too
    return access_control(
        keys,
        sorted([*cfg.robots, *cfg.sources]),
        identity=identity or access.identity,
        operators=access.operators,
        ros_keys=ros_map_keys(robots.values()) + ros_points_keys(cfg) + ros_diagnostics_keys(cfg),
        robot_keys=robot_keys,
    )


def access_summary(acl: dict[str, Any] | None, keys: SiteKeys, *, brief: bool = False) -> str:
    """What a start line says of access control: off (anyone may do anything), or on, for whom."""
    if acl is None:
        why = "" if brief else " (anyone who connects may read and write everything)"
        return f"access control off{why}"
    names = [str(n) for s in acl["subjects"] for k, v in s.items() if k != "id" for n in v]
    return f"access control on for {keys.prefix}/** (robots and operators: {', '.join(names)})"


REFUSALS_LOG = "off,zenoh_transport::unicast::establishment::accept=debug"
"""Zenoh's own log filter for a daemon that checks who connects: zenoh reports a refused session
(``UsrPwd extension - Recv OpenSyn. Invalid password.``) and each accepted one only at debug level of
its accept module, and nothing else is turned on. ``RUST_LOG`` overrides it."""


def log_refused_sessions(z: ZenohSettings) -> None:
    """When this side checks credentials (a users file, or mutual TLS), turn on zenoh's log of the
    sessions it accepts and refuses (on stderr, in zenoh's format); otherwise leave zenoh silent."""
    if z.auth.users_file is None and not z.tls.mutual:
        return
    zenoh.init_log_from_env_or(REFUSALS_LOG)
