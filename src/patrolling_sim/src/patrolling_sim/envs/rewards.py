"""Rewards of the learning environment, selected by name (docs/learning.md, "Rewards").

``T`` is the environment's time scale (:class:`~patrolling_sim.learned.observe.GraphTables`),
``I(t)`` the true idleness of the vertices at time t (the monitor's: time since the last
visit report), ``t0`` / ``t1`` the simulated times at the end of the previous step and of
this one (``dt = t1 - t0``):

- ``visit`` (per robot): ``I_v(t0) / T`` for the vertex v the robot reported visiting when
  it acted in this step (its decision carries the report), 0 when it did not act;
- ``avg_idleness_delta`` (team): ``-(mean_v I_v(t1) - A0) / T``, A0 the mean at the end of the
  previous step: minus the change of the average idleness over the step;
- ``avg_idleness`` (team): ``-dt * mean_v I_v(t1) / T^2``: the average idleness, weighted
  by the time it lasted;
- ``worst_idleness`` (team): ``-dt * max_v I_v(t1) / T^2``: the same with the worst vertex.

Team rewards are given to every robot still in the episode.
"""
REWARDS = ("visit", "avg_idleness_delta", "avg_idleness", "worst_idleness")


def team_reward(name: str, last_visit, now: float, dt: float, prev_avg: float, T: float):
    """(team part of reward ``name``, mean idleness now) for a step of ``dt`` s ending at
    ``now``; ``last_visit``: the monitor's visit times (module docstring). The team part
    of the per-robot ``visit`` is 0."""
    avg = now - sum(last_visit) / len(last_visit)      # every last visit is <= now
    if name == "avg_idleness_delta":
        return -(avg - prev_avg) / T, avg
    if name == "avg_idleness":
        return -dt * avg / (T * T), avg
    if name == "worst_idleness":
        return -dt * (now - min(last_visit)) / (T * T), avg
    return 0.0, avg
