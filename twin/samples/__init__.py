"""The sample lab as plain data (written as IFC by adapters.ifc.sample_lab)."""
