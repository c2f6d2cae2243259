"""From the graph's meshes to maps: the scene, the raster, one renderer, grids, 3D clouds."""
