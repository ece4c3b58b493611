#!/usr/bin/python3
"""Benchmark of the learning environment (patrolling_sim.envs, docs/learning.md): robot
decisions per second on one core, and the time per decision against a plain graph-mode run
of the same length, side by side in one process.

For each map and team size it runs, ``--repeat`` times each, alternating (environment,
plain, environment, ...: a change of the machine's load hits both alike), and keeps the
fastest of each:

- the environment (``PatrolParallelEnv``, flat observations, neighbour actions, reward
  ``visit``) for ``--duration`` simulated s with a random policy over the valid actions (a
  ready robot draws uniformly among its action mask; the others get 0, which they ignore);
  decisions = actions applied; the time includes reset, observations, rewards and infos;
- a plain graph-mode run (``GraphSimulator(...).run(write=False)``, no result files) of RAND
  (a random neighbour: the same kind of decisions) with the same map, team, duration and
  seed; decisions = visit reports.

CPU time is ``time.process_time()`` of this process. Prints one table row per case: env
decisions/s, env and plain us per decision (fastest runs), their ratio (issue targets:
>= 10,000 decisions/s on grid with 4 robots, ratio <= 3), and the median over the pairs of
the ratio within a pair (an environment run and the plain run right after it: on a loaded
machine the two runs of a pair see about the same load, the fastest runs may not).

Usage:
    bench/env_bench.py [--maps grid broughton] [--robots 4 12] [--duration 1800]
                       [--repeat 3] [--seed 0]
"""
import argparse
import glob
import os
import platform
import random
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))
for _site in glob.glob(os.path.join(ROOT, ".venv", "lib", "python3*", "site-packages")):
    sys.path.append(_site)                            # gymnasium, pettingzoo (make setup)

from patrolling_sim.envs.parallel import PatrolParallelEnv  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402


def env_run(map_name, robots, duration, seed):
    """(CPU s, decisions) of one episode with a random policy over valid actions."""
    env = PatrolParallelEnv(map=map_name, robots=robots, duration=duration)
    env.reset(seed=seed)                # builds the graph tables once (not timed)
    rng = random.Random(seed)
    t0 = time.process_time()
    obs, infos = env.reset(seed=seed)
    decisions = 0
    while env.agents:
        acts = {}
        for a in env.agents:
            info = infos[a]
            if info["ready"]:
                mask = info["action_mask"]
                acts[a] = rng.choice([k for k in range(len(mask)) if mask[k]])
                decisions += 1
            else:
                acts[a] = 0
        obs, rew, term, trunc, infos = env.step(acts)
    return time.process_time() - t0, decisions


def plain_run(map_name, robots, duration, seed):
    """(CPU s, decisions) of the same run in plain graph mode (RAND, no files)."""
    cfg = GraphSimConfig(map=map_name, robots=robots, alg="RAND", duration=duration, seed=seed)
    sim = GraphSimulator(cfg)
    t0 = time.process_time()
    sim.run(write=False)
    cpu = time.process_time() - t0
    return cpu, sum(c + 1 for c in sim.monitor.visits)


def per_decision(run):
    return run[0] / max(run[1], 1)


def best_pair(repeat, *args):
    """(fastest environment run, fastest plain run, median pair ratio) of ``repeat``
    alternated pairs (``args``: map, robots, duration, seed)."""
    env, plain = [], []
    for _ in range(repeat):
        env.append(env_run(*args))
        plain.append(plain_run(*args))
    ratios = sorted(per_decision(e) / per_decision(p) for e, p in zip(env, plain))
    mid = len(ratios) // 2
    median = ratios[mid] if len(ratios) % 2 else (ratios[mid - 1] + ratios[mid]) / 2
    return min(env, key=per_decision), min(plain, key=per_decision), median


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["grid", "broughton"])
    ap.add_argument("--robots", nargs="+", type=int, default=[4, 12])
    ap.add_argument("--duration", type=float, default=1800.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    print(f"# {platform.node()}, python {platform.python_version()}, load average "
          f"{os.getloadavg()[0]:.1f}; {a.duration:g} sim s, best of {a.repeat}")
    print("| map | robots | env decisions | env decisions/s | env us/decision "
          "| plain us/decision (RAND) | ratio | ratio, median of pairs |")
    print("|---|---|---|---|---|---|---|---|")
    for m in a.maps:
        for n in a.robots:
            (ecpu, edec), (pcpu, pdec), med = best_pair(a.repeat, m, n, a.duration, a.seed)
            e_us, p_us = 1e6 * ecpu / edec, 1e6 * pcpu / pdec
            print(f"| {m} | {n} | {edec} | {edec / ecpu:,.0f} | {e_us:.0f} | {p_us:.0f} "
                  f"| {e_us / p_us:.2f} | {med:.2f} |", flush=True)


if __name__ == "__main__":
    main()
