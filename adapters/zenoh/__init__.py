"""The Zenoh adapter: the daemon's publishers, queryables and subscribers, and the robot-side client.

Modules: ``session`` (configuration), ``keys`` (key expressions), ``latched`` (the latched map
publisher and the subscription that follows one), ``daemon`` (binds a :class:`twin.live.TwinService`
to a session), ``client`` (what robots and the CLI use), ``ros_maps`` and ``ros_watch`` (maps in ROS 2
layouts, served and watched), ``access`` (access control), ``router`` (routers and map storage).
"""
