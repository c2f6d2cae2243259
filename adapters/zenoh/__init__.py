"""The Zenoh adapter: the daemon's publishers, queryables and subscribers, and the robot-side client.

Modules: ``session`` (configuration), ``keys`` (key expressions), ``daemon`` (binds a
:class:`twin.live.TwinService` to a session), ``client`` (what robots and the CLI use).
"""
