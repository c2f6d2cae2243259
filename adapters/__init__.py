"""The edges of building-twin: translate between the core's records and the outside world.

- ``adapters.ifc``: IFC files -> ``twin.records.BuildingModel`` (ifcopenshell)
- ``adapters.ifc.sample_lab``: the bundled sample building (``twin.lab_layout``) written with ifcopenshell.api
- ``adapters.ros``: CDR ``nav_msgs/OccupancyGrid`` messages and nav2 map_server files
"""
