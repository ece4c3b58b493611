"""Where the robots start.

- :mod:`~patrolling_sim.startpos.initial_poses` -- the original's ``initial_poses.txt`` table
  and computed spreads
- :mod:`~patrolling_sim.startpos.optimised`     -- ``--initpos optimised``: start vertices
  chosen for an algorithm
- :mod:`~patrolling_sim.startpos.explicit`      -- stated starts (``vertices:...``, a start
  file) and ``random``
- :mod:`~patrolling_sim.startpos.resolve`       -- an ``initpos`` setting resolved to start
  positions
"""
