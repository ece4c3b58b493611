"""spqrel_nav_lite: map server, localisation and navigation nodes behind move_base.

The package depends on nothing of the patrolling application. Two of its modules are its
public API for other packages, kept stable for them:

- :mod:`spqrel_nav_lite.mapio` -- occupancy maps in map_server format (``load_map``,
  ``OccupancyMap``), the one map loader of the workspace;
- :mod:`spqrel_nav_lite.errors` -- ``InputError`` (a bad input, with a one-line message) and
  ``MapFormatError``, the base of every input error of the workspace.
"""
