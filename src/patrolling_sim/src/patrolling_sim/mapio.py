"""Occupancy maps in map_server format: the loader lives in the navigation package
(``spqrel_nav_lite.mapio``), which must work on its own; the core uses that one loader."""
from spqrel_nav_lite.mapio import (FREE, OCCUPIED, UNKNOWN, OccupancyMap,  # noqa: F401
                                   image_to_occupancy, load_map, read_image)
