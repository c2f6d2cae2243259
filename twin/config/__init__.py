"""Configuration: ``config/default.toml`` merged with an optional user file, one schema per table.

Each table of the file is a pydantic model (:mod:`twin.config.tables`, :mod:`twin.config.robots`):
its keys' types, bounds, defaults and descriptions in one place, unknown keys and wrong values refused
with an error that names the key (``Configuration [maps] margin_m: expected a number <= 100.0, got
500.``). The core knows no transport: the tables of the adapters (``[zenoh]``, ``[rerun]``, the
remote store's keys in ``[store]``) are :class:`ConfigSection` schemas in those adapters, which the
composition root (``adapters/cli``) hands to :func:`load_config`. :func:`config_schema` is the JSON
Schema editors use (``config/schema.json``).

Example::

    cfg = load_config(Path("site.toml"))     # or load_config() for the defaults
    skill = cfg.skill("lab-navigation")
"""

from __future__ import annotations

from twin.config.base import ConfigSection, ConfigTable
from twin.config.fusion import FusionClassRules, FusionRules
from twin.config.load import DEFAULT_CONFIG, Config, config_schema, file_model, load_config
from twin.config.robots import DEFAULT_ROBOT_MAPS, RESERVED_TOPICS, DetectionConfig, RobotConfig, RosLayout
from twin.config.sources import LevelConfig, SourceConfig
from twin.config.tables import KERNELS, RIGHTS, ImportConfig, Limits, Right

__all__ = [
    "DEFAULT_CONFIG",
    "DEFAULT_ROBOT_MAPS",
    "KERNELS",
    "RESERVED_TOPICS",
    "RIGHTS",
    "Config",
    "ConfigSection",
    "ConfigTable",
    "DetectionConfig",
    "FusionClassRules",
    "FusionRules",
    "ImportConfig",
    "LevelConfig",
    "Limits",
    "Right",
    "RobotConfig",
    "RosLayout",
    "SourceConfig",
    "config_schema",
    "file_model",
    "load_config",
]
