"""Learning environments over graph mode (docs/learning.md): a PettingZoo ``ParallelEnv``
(:class:`~patrolling_sim.envs.parallel.PatrolParallelEnv`), its AEC form, a single-agent
Gymnasium wrapper, and seeded random patrol graphs; the observations and beliefs are
:mod:`patrolling_sim.learned`'s, shared with the ``POLICY`` algorithm. The only subpackage
that imports gymnasium and pettingzoo (PyPI, scripts/requirements-learning.txt); nothing below
it and no ROS node imports it."""
