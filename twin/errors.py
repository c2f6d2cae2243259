"""Errors of the core, one per role. Messages name the offending value."""

from __future__ import annotations


class TwinError(Exception):
    """Base of every error building-twin raises on purpose."""


class ModelError(TwinError):
    """A building model (IFC file or records) is unusable: missing, malformed, unsupported or empty."""


class StoreError(TwinError):
    """The graph store cannot be opened, written or queried as asked."""


class StoreNotFoundError(StoreError):
    """There is no store where one was to be opened (nothing was imported there yet)."""


class StoreNotEmptyError(StoreError):
    """A model was to be imported into a store that already holds one."""


class StoreUnavailableError(StoreError):
    """A remote graph store (a SPARQL endpoint) cannot be reached, or did not answer in time."""


class StoreWriteError(StoreError):
    """The store could not write (e.g. its file system is full: ENOSPC); nothing of the change is kept."""


class QueryError(StoreError):
    """A SPARQL query does not parse, or is not allowed (e.g. an update on a read-only endpoint)."""


class SkillError(TwinError):
    """A skill profile is invalid or unknown."""


class MapError(TwinError):
    """A map cannot be built or read (unknown storey, bad grid file, inconsistent frame)."""


class ConfigError(TwinError):
    """The configuration file is missing, malformed or has an invalid value."""


class ObservationError(TwinError):
    """An observation (robot-reported change) is malformed, exceeds a limit or is not allowed."""


class ExplainError(TwinError):
    """A map cell that cannot be explained: an unknown map, or a point outside it."""


class SnapshotError(TwinError):
    """A derived-state snapshot is missing, damaged, of another format, or does not match the store."""


class RouteError(SkillError):
    """A routes skill is invalid, or cannot make a route graph of the building (e.g. a storey with no
    free space for its robot, a robot wider than every door)."""
