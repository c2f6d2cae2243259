"""The Zenoh key expressions of one site (see docs/zenoh-keys.md).

Example::

    keys = SiteKeys("twin/lab")
    keys.map("ground-floor", "navigation")     # "twin/lab/map/ground-floor/navigation"
    keys.robot_of(keys.observe("robot1"))      # "robot1"
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from adapters.zenoh.errors import TransportError

_CHUNK = re.compile(r"^[A-Za-z0-9_.-]{1,128}$")


def check_chunk(value: str, what: str) -> str:
    """``value`` if it can be one chunk of a key expression (no ``/``, wildcards or ``$``)."""
    if not _CHUNK.match(value):
        msg = f"{what} {value!r} cannot be part of a key: use 1-128 of [A-Za-z0-9_.-]."
        raise TransportError(msg)
    return value


@dataclass(frozen=True, slots=True)
class SiteKeys:
    prefix: str

    def map(self, storey: str, skill: str) -> str:
        return f"{self.prefix}/map/{storey}/{skill}"

    def map_updates(self, storey: str, skill: str) -> str:
        return f"{self.prefix}/map_updates/{storey}/{skill}"

    @property
    def maps(self) -> str:
        return f"{self.prefix}/map/**"

    def points_map(self, storey: str, skill: str) -> str:
        """A points skill's cloud: ``points/<storey>/<skill>``."""
        return f"{self.prefix}/points/{check_chunk(storey, 'Storey key')}/{check_chunk(skill, 'Skill name')}"

    @property
    def points(self) -> str:
        """Every points skill's cloud (``points/**``)."""
        return f"{self.prefix}/points/**"

    def observations(self, robot: str) -> str:
        return f"{self.prefix}/observations/{check_chunk(robot, 'Robot name')}"

    def observe(self, robot: str) -> str:
        return f"{self.prefix}/observe/{check_chunk(robot, 'Robot name')}"

    @property
    def all_map_updates(self) -> str:
        return f"{self.prefix}/map_updates/**"

    @property
    def everything(self) -> str:
        """Every key of the site (what operators may do)."""
        return f"{self.prefix}/**"

    @property
    def all_observations(self) -> str:
        """Every robot's best-effort observations (``observations/*``)."""
        return f"{self.prefix}/observations/*"

    @property
    def all_observe(self) -> str:
        """Every robot's acked observation path (``observe/*``)."""
        return f"{self.prefix}/observe/*"

    @property
    def skills_listing(self) -> str:
        """What a ``get`` of every skill profile asks (``skills/**``)."""
        return f"{self.prefix}/skills/**"

    def skill(self, name: str) -> str:
        return f"{self.prefix}/skills/{check_chunk(name, 'Skill name')}"

    @property
    def skills(self) -> str:
        return f"{self.prefix}/skills/*"

    @property
    def sparql(self) -> str:
        return f"{self.prefix}/sparql"

    @property
    def status(self) -> str:
        return f"{self.prefix}/status"

    @property
    def explain(self) -> str:
        return f"{self.prefix}/explain"

    def robot_storey(self, robot: str) -> str:
        """Where a robot's current storey key is put and got: ``robots/<robot>/storey``."""
        return f"{self.prefix}/robots/{check_chunk(robot, 'Robot name')}/storey"

    @property
    def robot_storeys(self) -> str:
        return f"{self.prefix}/robots/*/storey"

    @property
    def daemon(self) -> str:
        """The daemon's liveliness token."""
        return f"{self.prefix}/daemon"

    def last(self, key: str) -> str:
        """The last chunk of ``key`` (the robot of an observation key, the name of a skill key)."""
        return str(key).rsplit("/", 1)[-1]

    def robot_of(self, key: str) -> str:
        return self.last(key)

    def map_of(self, key: str) -> tuple[str, str] | None:
        """``(storey, skill)`` of a map key of this site, or None."""
        parts = str(key).removeprefix(self.prefix + "/").split("/")
        if len(parts) == 3 and parts[0] in ("map", "map_updates"):
            return parts[1], parts[2]
        return None
