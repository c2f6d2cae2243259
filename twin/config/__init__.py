"""Configuration: ``config/default.toml`` merged with an optional user file, one schema per table.

Each table of the file is a pydantic model (:mod:`twin.config.tables`, :mod:`twin.config.robots`):
its keys' types, bounds, defaults and descriptions in one place, unknown keys and wrong values refused
with an error that names the key (``Configuration [maps] margin_m: expected a number <= 100.0, got
500.``). The core knows no transport: the tables of the adapters (``[zenoh]``, ``[rerun]``, ``[ros]``,
the remote store's keys in ``[store]``, the ROS 2 keys of each ``[robots.NAME]`` and
``[sources.NAME]``) are :class:`ConfigSection` schemas in those adapters, which the composition root
(``adapters/cli``) hands to :func:`load_config`. :func:`config_schema` is the JSON
Schema editors use (``config/schema.json``).

Example::

    cfg = load_config(Path("site.toml"))     # or load_config() for the defaults
    skill = cfg.skill("lab-navigation")
"""

from __future__ import annotations

from twin.config.base import ConfigSection, ConfigTable
from twin.config.fusion import FusionClassRules, FusionRules
from twin.config.load import DEFAULT_CONFIG, Config, config_schema, file_model, load_config
from twin.config.robots import RobotConfig, RobotName
from twin.config.sources import SourceConfig, SourceKind
from twin.config.tables import KERNELS, RIGHTS, ImportConfig, Limits, Right

__all__ = [
    "DEFAULT_CONFIG",
    "KERNELS",
    "RIGHTS",
    "Config",
    "ConfigSection",
    "ConfigTable",
    "FusionClassRules",
    "FusionRules",
    "ImportConfig",
    "Limits",
    "Right",
    "RobotConfig",
    "RobotName",
    "SourceConfig",
    "SourceKind",
    "config_schema",
    "file_model",
    "load_config",
]
