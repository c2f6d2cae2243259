"""IFC import: read an IFC file (any of IFC2X3, IFC4, IFC4X3) into the core's ``BuildingModel`` records.

Example::

    from adapters.ifc import read_model
    model = read_model(Path("model.ifc"), static_types=("IfcWall",))
"""

from __future__ import annotations

from adapters.ifc.errors import IfcFileError
from adapters.ifc.materials import material_names
from adapters.ifc.read_model import read_model

__all__ = ["IfcFileError", "material_names", "read_model"]
