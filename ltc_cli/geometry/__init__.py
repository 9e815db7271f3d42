"""Pure numpy geometry: Z-oriented boxes, cameras and poses, footprint polygons."""
