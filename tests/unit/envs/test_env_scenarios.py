"""The learning environment is graph mode: a scripted policy with CR's rule gives the very
visits and idleness of a graph-mode CR run; beliefs follow the delivered messages; failed
robots leave the episode; random graphs are seeded and connected."""
import random

import networkx as nx
import numpy as np
import pytest

from patrolling_sim.agent.factory import agent_seed
from patrolling_sim.algorithms.base import argmax_random
from patrolling_sim.envs.graphs import RandomGraphSpec, random_patrol_graph
from patrolling_sim.envs.parallel import PatrolParallelEnv
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator


def record_visits(sim):
    """Wrap ``sim.monitor.visit`` to record every visit report (robot, vertex, time)."""
    seen = []
    visit = sim.monitor.visit

    def recording(robot, vertex, now):
        seen.append((robot, vertex, now))
        return visit(robot, vertex, now)
    sim.monitor.visit = recording
    return seen


class ScriptedCR:
    """CR's rule (algorithms/cr.py) from what the environment tells a robot: its own visits
    (the vertex and time of each of its decisions), its neighbour slots, and its own
    generator seeded as graph mode seeds the robot's strategy."""

    def __init__(self, env, seed):
        g = env.sim.g
        self.g = g
        self.rng = [random.Random(agent_seed(seed, i)) for i in range(env.opt.robots)]
        self.last = [[0.0] * g.n for _ in range(env.opt.robots)]
        self.first = [True] * env.opt.robots
        for i, v in enumerate(env.sim.start_vertices):
            self.last[i][v] = 0.1

    def act(self, i, info):
        v, now = info["vertex"], info["time"]
        if self.first[i]:           # the first decision sees an all-zero table (base.start)
            idle = [0.0] * self.g.n
            self.first[i] = False
        else:
            self.last[i][v] = now
            idle = [now - t for t in self.last[i]]
        nbrs = self.g.neighbor_ids(v)
        return nbrs.index(argmax_random(nbrs, lambda w: idle[w], self.rng[i]))


@pytest.mark.parametrize("map_name, robots, seed, gwait, attrition", [
    ("grid", 4, 0, 0.0, "none"), ("cumberland", 3, 7, 2.0, "none"),
    ("grid", 4, 3, 0.0, "2@300")])
def test_scripted_cr_through_the_env_is_graph_mode_cr(map_name, robots, seed, gwait, attrition):
    duration = 1800.0
    env = PatrolParallelEnv(map=map_name, robots=robots, duration=duration, gwait=gwait,
                            attrition=attrition)
    obs, infos = env.reset(seed=seed)
    got = record_visits(env.sim)
    policy = ScriptedCR(env, seed)
    while env.agents:
        acts = {a: policy.act(env.agent_ids[a], infos[a]) for a in env.agents
                if infos[a]["ready"]}
        obs, rew, term, trunc, infos = env.step(acts)
    ref = GraphSimulator(GraphSimConfig(map=map_name, robots=robots, alg="CR",
                                        duration=duration, seed=seed, gwait=gwait,
                                        attrition=attrition))
    want = record_visits(ref)
    stats = ref.run(write=False)
    assert len(got) > 100 * robots
    assert got == want
    mine = env.final_stats
    assert (mine.global_avg, mine.global_max, mine.interferences, mine.cycles) == \
        (stats.global_avg, stats.global_max, stats.interferences, stats.cycles)


def play(env, seed, steps=None):
    rng = np.random.default_rng(seed)
    obs, infos = env.reset(seed=seed)
    out = []
    n = 0
    while env.agents and (steps is None or n < steps):
        acts = {a: int(rng.choice(np.flatnonzero(infos[a]["action_mask"]))) for a in env.agents}
        res = env.step(acts)
        out.append(res)
        infos = res[4]
        n += 1
    return out


def test_beliefs_follow_the_delivered_messages():
    env = PatrolParallelEnv(map="grid", robots=3, duration=300.0)
    play(env, 1)
    b, mon, t = env.board, env.sim.monitor, env.sim.t
    visited = [v for v in range(env.sim.g.n) if mon.visits[v] >= 0 and mon.last_visit[v] < t]
    assert len(visited) > 10
    for i in range(3):        # perfect links: every robot knows every report
        assert all(b.last_visit[i, v] == mon.last_visit[v] for v in visited)
        assert all(b.mate_time[i][j] > 0 for j in range(3) if j != i)
    lossy = PatrolParallelEnv(map="grid", robots=3, duration=300.0, comm="bernoulli:p=1")
    play(lossy, 1)
    b, mon = lossy.board, lossy.sim.monitor
    assert all(t == 0 for row in b.mate_time for t in row), \
        "nothing delivered: teammates stay where they started"
    for i in range(3):        # a robot believes only its own visits
        mine = b.last_visit[i] > 0.1
        assert mine.any()
        assert (b.last_visit[i][mine] <= np.asarray(mon.last_visit)[mine]).all()
        assert (b.last_visit[i] < np.asarray(mon.last_visit)).any()
    assert lossy.sim.comm_counters()[0]["results_lost"] > 0


def test_a_failed_robot_is_terminated_and_leaves():
    env = PatrolParallelEnv(map="grid", robots=3, duration=200.0, attrition="1@50")
    steps = play(env, 2)
    ended = [k for k, (_, _, term, _, _) in enumerate(steps) if term.get("robot_1")]
    assert len(ended) == 1
    k = ended[0]
    assert steps[k][4]["robot_1"]["time"] >= 50.0
    assert all("robot_1" not in s[0] for s in steps[k + 1:])
    last = steps[-1]
    assert set(last[3]) == {"robot_0", "robot_2"} and all(last[3].values())
    assert env.agents == []


def test_random_graphs_are_seeded_connected_and_bounded():
    spec = RandomGraphSpec(n=25, max_degree=4)
    a, b, c = (random_patrol_graph(s, spec) for s in (3, 3, 4))
    assert nx.is_isomorphic(a, b) and [a.nodes[v]["pos"] for v in a] == \
        [b.nodes[v]["pos"] for v in b]
    assert [a.nodes[v]["pos"] for v in a] != [c.nodes[v]["pos"] for v in c]
    for g in (a, c):
        und = nx.Graph(g)
        assert nx.is_connected(und) and max(d for _, d in und.degree()) <= 4
        assert all(g.has_edge(w, u) for u, w in g.edges())
    env = PatrolParallelEnv(map="random:n=20,max_degree=4", robots=3, duration=120.0)
    env.reset(seed=11)
    first = env.sim.g.pos.copy()
    assert env.sim.g.n == 20 and env.action_space("robot_0").n == 4
    env.reset(seed=12)
    assert not np.array_equal(first, env.sim.g.pos)
    env.reset(seed=11)
    assert np.array_equal(first, env.sim.g.pos)
    assert play(env, 11, steps=30)
    env.close()


def flat_from_scratch(env, i, ready):
    """Robot ``i``'s flat observation computed directly from the beliefs (the layout of
    docs/learning.md), to check the environment's event-by-event bookkeeping."""
    tab, b, t = env.tab, env.board, env.sim.t
    S, T, D = tab.S, tab.T, tab.D
    cur = int(b.current[i])
    x, y = tab.pos[cur]
    out = [x / S, y / S, 1.0 if ready else 0.0]
    nbrs = env.sim.g.neighbor_ids(cur)
    for k in range(D):
        if k < len(nbrs):
            w = nbrs[k]
            out += [1.0, (t - b.last_visit[i, w]) / T,
                    env.sim.g.arc_cost(cur, w) * env.sim.g.resolution / S,
                    (tab.pos[w][0] - x) / S, (tab.pos[w][1] - y) / S]
        else:
            out += [0.0] * 5
    for j in range(env.opt.robots):
        if j != i:
            v, n = b.mate_vertex[i][j], b.mate_next[i][j]
            out += [(tab.pos[v][0] - x) / S, (tab.pos[v][1] - y) / S,
                    (tab.pos[n][0] - x) / S, (tab.pos[n][1] - y) / S,
                    (t - b.mate_time[i][j]) / T]
    if env.opt.action == "goal":
        out += [(t - lv) / T for lv in b.last_visit[i]]
        out += [1.0 if v == cur else 0.0 for v in range(tab.n)]
    return np.array(out)


@pytest.mark.parametrize("kwargs", [dict(comm="bernoulli:p=0.3"), dict(action="goal")])
def test_flat_observations_match_their_definition(kwargs):
    env = PatrolParallelEnv(map="cumberland", robots=4, duration=400.0, **kwargs)
    rng = np.random.default_rng(0)
    obs, infos = env.reset(seed=4)
    checked = 0
    while env.agents:
        for a in env.agents:
            want = flat_from_scratch(env, env.agent_ids[a], infos[a]["ready"])
            assert np.allclose(obs[a], want, rtol=1e-5, atol=1e-5), a
            checked += 1
        acts = {a: int(rng.choice(np.flatnonzero(infos[a]["action_mask"]))) for a in env.agents}
        obs, rew, term, trunc, infos = env.step(acts)
    assert checked > 200
