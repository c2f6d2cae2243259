"""The edges of building-twin: translate between the core's records and the outside world.

- ``adapters.ifc``: IFC files -> ``twin.records.BuildingModel`` (ifcopenshell); ``sample_lab`` writes
  the bundled sample building (``twin.samples.lab_layout``) with ifcopenshell.api
- ``adapters.ros``: CDR messages (``nav_msgs/OccupancyGrid`` and updates), nav2 map_server files,
  PNG previews, rmw_zenoh's and zenoh-bridge-ros2dds's key layouts; ``settings``: ``[ros]`` and the ROS 2
  keys of ``[robots.NAME]`` and ``[sources.NAME]``
- ``adapters.zenoh``: the daemon's publishers, queryables and subscribers, the robot-side client,
  the ROS 2 map servers, access control and routers
- ``adapters.sparql``: the ``GraphStore`` on a remote SPARQL 1.1 server
- ``adapters.rerun``: the recorder sink and the reader of recordings
- ``adapters.cli``: the ``twin`` command, the composition root that wires them to the core
"""
