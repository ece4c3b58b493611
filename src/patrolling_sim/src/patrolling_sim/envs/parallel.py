"""The PettingZoo ``ParallelEnv`` over graph mode (docs/learning.md): the robots of a
:class:`~patrolling_sim.graphsim.simulator.GraphSimulator` run the ordinary life cycle
(motion, interference, goal wait, communication model, attrition) with
:class:`~patrolling_sim.envs.strategy.EnvStrategy` as their strategy, so every decision a
robot's life cycle asks for is taken by the policy.

A step: the actions of the ready robots are applied at the current simulated time (each
ready robot's decision reports its visit, tells its teammates, and sends its goal, as any
strategy's decision does), then the simulation runs until some robot must decide again, or
the time limit. Robots that are not ready ignore their action.
"""
import os
import random
import shutil
import tempfile
import warnings
import weakref

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.envs.graphs import random_patrol_graph, write_map_bundle
from patrolling_sim.envs.options import EnvOptions
from patrolling_sim.envs.render import draw_frame
from patrolling_sim.envs.rewards import team_reward
from patrolling_sim.envs.strategy import BOARD_PARAM, DecisionBoard, EnvStrategy
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.starts import start_vertices_of
from patrolling_sim.learned import observe
from patrolling_sim.learned.slots import K as SLOT_K, SlotTables, slot_features
from patrolling_sim.model.graph import PatrolGraph


class PatrolParallelEnv(ParallelEnv):
    """Multi-robot patrolling as a PettingZoo ``ParallelEnv``; arguments: :class:`EnvOptions`
    (docs/learning.md). Agents ``"robot_0"``...; ``infos[a]`` has ``ready``, ``dt`` (sim s
    since the previous step), ``time``, ``vertex``, ``action_mask`` and ``metrics``."""

    metadata = {"name": "patrolling_sim_v0", "render_modes": ["rgb_array"],
                "is_parallelizable": True, "render_fps": 5}

    def __init__(self, **kwargs):
        unknown = set(kwargs) - set(EnvOptions.__dataclass_fields__)
        if unknown:
            raise PatrolInputError(f"unknown argument(s): {', '.join(sorted(unknown))} "
                                   f"(known: {', '.join(EnvOptions.__dataclass_fields__)})")
        self.opt = o = EnvOptions(**kwargs).check()
        self.render_mode = o.render_mode
        self.spec_random = o.random_spec
        self._tmp = None
        self._graphs = {}                 # map path -> (PatrolGraph, GraphTables)
        self._seeds = random.Random(o.seed if o.seed is not None else 0)
        if self.spec_random is not None:
            self._tmp = tempfile.mkdtemp(prefix="patrolling_env_")
            weakref.finalize(self, shutil.rmtree, self._tmp, True)
            n, degree = self.spec_random.n, self.spec_random.max_degree
        else:
            self._config(o.map, 0).validate()
            path = paths.map_files(o.map)[1]
            pg = PatrolGraph.load(path)
            self._graphs = {path: (pg, None)}
            n, degree = pg.n, max(len(pg.neighbor_ids(v)) for v in range(pg.n))
        if o.max_degree is not None and o.max_degree < degree:
            raise PatrolInputError(f"argument max_degree: the graph has a vertex of degree "
                                   f"{degree}, above max_degree {o.max_degree}")
        self.max_degree = o.max_degree or degree
        self.n_vertices = n
        self.possible_agents = [f"robot_{i}" for i in range(o.robots)]
        self.agent_ids = {a: i for i, a in enumerate(self.possible_agents)}
        self._make_spaces()
        self.agents = []
        self.sim = None

    # -- spaces ---------------------------------------------------------------------------
    def _make_spaces(self):
        o, D, V, B = self.opt, self.max_degree, self.n_vertices, observe.BOUND
        if o.observation == "flat":
            size = observe.flat_size(o.robots, D, V, o.action == "goal")
            obs = [spaces.Box(-B, B, (size,), np.float32) for _ in range(o.robots)]
        elif o.observation == "slots":
            obs = [spaces.Box(-B, B, (D, SLOT_K), np.float32) for _ in range(o.robots)]
        else:
            obs = [spaces.Graph(spaces.Box(-B, B, (observe.NODE_FEATURES,), np.float32),
                                spaces.Box(0.0, B, (1,), np.float32))
                   for _ in range(o.robots)]
        act = [spaces.Discrete(D if o.action == "neighbour" else V) for _ in range(o.robots)]
        self.observation_spaces = dict(zip(self.possible_agents, obs))
        self.action_spaces = dict(zip(self.possible_agents, act))
        self.state_space = spaces.Box(-B, B, (V + 4 * o.robots,), np.float32)

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    # -- episode set-up -------------------------------------------------------------------
    def _config(self, map_path, seed, board=None):
        o = self.opt
        initpos = o.initpos or ("random" if self.spec_random is not None else "default")
        return GraphSimConfig(map=map_path, robots=o.robots, alg="CR", duration=o.duration,
                              seed=seed, speed=o.speed, gwait=o.gwait, comm_delay=o.comm_delay,
                              loss=o.loss, initpos=initpos, goal_fail=o.goal_fail,
                              interference=o.interference, travel=o.travel, comm=o.comm,
                              attrition=o.attrition,
                              params={} if board is None else {BOARD_PARAM: board})

    def _graph(self, map_path):
        """The PatrolGraph and observation tables of ``map_path`` (the last one is kept)."""
        path = paths.map_files(map_path)[1]
        pg, tab = self._graphs.get(path, (None, None))
        if pg is None:
            pg = PatrolGraph.load(path)
        if tab is None:
            tab = observe.GraphTables(pg, self.opt.robots, self.opt.speed, self.max_degree)
        self._graphs = {path: (pg, tab)}
        return pg, tab

    def _slot_tables(self, tab):
        """The slot observation's tables of ``tab`` (kept with the graph's tables)."""
        st = getattr(tab, "slot_tables", None)
        if st is None:
            st = tab.slot_tables = SlotTables(tab, self.opt.speed)
        return st

    def _map_for(self, seed):
        if self.spec_random is None:
            return self.opt.map
        name = f"random_{seed}"
        G = random_patrol_graph(seed, self.spec_random, name=name)
        for old in os.listdir(self._tmp):
            shutil.rmtree(os.path.join(self._tmp, old), ignore_errors=True)
        return write_map_bundle(G, self._tmp, name)

    def reset(self, seed=None, options=None):
        """A new episode (a new random graph for ``map="random..."``) from ``seed`` (None:
        the next seed of the environment's own sequence, started from ``seed=``)."""
        if seed is None:
            seed = self._seeds.randrange(2 ** 31)
        self.seed_used = int(seed)
        map_path = self._map_for(self.seed_used)
        pg, self.tab = self._graph(map_path)
        cfg0 = self._config(map_path, self.seed_used)
        starts = start_vertices_of(cfg0.validate(), pg)
        self.board = DecisionBoard(self.opt.robots, pg.n, starts)
        self.flat = None
        self.slot_tables = None
        if self.opt.observation == "slots":
            self.slot_tables = self._slot_tables(self.tab)
        elif self.opt.observation == "flat":
            self.flat = self.board.listener = observe.FlatObservations(
                self.tab, self.board, self.opt.action == "goal")
        self.sim = GraphSimulator(self._config(map_path, self.seed_used, self.board),
                                  start_vertices=starts, pgraph=pg, strategy_class=EnvStrategy)
        self.map_path = map_path
        self.agents = list(self.possible_agents)
        self._live = list(enumerate(self.agents))     # (id, agent) of self.agents
        self._masks = (self.tab.mask_neighbour_rows if self.opt.action == "neighbour"
                       else self.tab.mask_goal_rows)
        self.sim.begin()
        self._cores = [r.core for r in self.sim.robots]
        self._t_prev = 0.0
        self._over = self.sim.advance(self.board.pending.__len__)
        self._ready = self._take_ready()
        self.final_stats = None
        self._prev_avg = team_reward("avg_idleness_delta", self.sim.monitor.last_visit,
                                     self.sim.t, 0.0, 0.0, self.tab.T)[1]
        return self._observations(), self._infos(0.0)

    # -- stepping -------------------------------------------------------------------------
    def _take_ready(self):
        pending, cores = self.board.pending, self._cores
        ready = [i for i in dict.fromkeys(pending) if not cores[i].failed]
        pending.clear()
        return ready

    def _goal_of(self, i, a):
        """The vertex robot ``i`` is sent to by action ``a`` (an invalid action, see the
        mask, is wrapped onto a valid one: modulo the degree, or the vertex count)."""
        cur = int(self.board.current[i])
        a = int(a)
        if self.opt.action == "neighbour":
            nbrs = self.tab.nbr_lists[cur]
            return nbrs[a % len(nbrs)] if nbrs else cur
        return a % self.n_vertices

    def _apply(self, actions):
        """Apply the ready robots' actions; returns {robot: visit reward}."""
        gained = {}
        mon, t = self.sim.monitor, self.sim.t
        agents, current, cores = self.possible_agents, self.board.current, self._cores
        for i in self._ready:
            a = actions.get(agents[i])
            if a is None:
                continue                    # not decided: the life cycle asks again in 0.5 s
            v = self._goal_of(i, a)
            core = cores[i]
            cur = int(current[i])
            before = mon.last_visit[cur]
            core.strategy.next = v
            core.redirect(v)
            if mon.last_visit[cur] != before:
                gained[i] = (t - before) / self.tab.T
        return gained

    def step(self, actions):
        if not self.agents:
            raise PatrolInputError("step() after the episode ended: call reset()")
        gained = self._apply(actions)
        over = self._over = self.sim.advance(self.board.pending.__len__)
        self._ready = self._take_ready()
        t = self.sim.t
        dt, self._t_prev = t - self._t_prev, t
        if over:
            self.final_stats = self.sim.finish()
        team, self._prev_avg = team_reward(self.opt.reward, self.sim.monitor.last_visit, t,
                                           dt, self._prev_avg, self.tab.T)
        visit, cores, over, agents = self.opt.reward == "visit", self._cores, bool(over), \
            self.agents
        rewards = dict.fromkeys(agents, float(team + (0.0 if visit else 0)))
        if visit:
            for i, g in gained.items():              # ready robots: all in the episode
                rewards[self.possible_agents[i]] = float(team + g)
        terms = dict.fromkeys(agents, False)
        truncs = dict.fromkeys(agents, over)
        failed = [a for i, a in self._live if cores[i].failed]
        for a in failed:
            terms[a], truncs[a] = True, False
        obs = self._observations()
        infos = self._infos(dt)
        if failed or over:
            self._live = [(i, a) for i, a in self._live if not (terms[a] or truncs[a])]
            self.agents = [a for _, a in self._live]
        return obs, rewards, terms, truncs, infos

    # -- observations, infos, state -------------------------------------------------------
    def _ready_vector(self):
        out = [0.0] * self.opt.robots
        for i in self._ready:
            out[i] = 1.0
        return out

    def _observations(self):
        b, t = self.board, self.sim.t
        if self.flat is not None:
            m = self.flat.observe(t, self._ready_vector())
            if len(self._live) == len(m):
                return dict(zip(self.agents, m))
            return {a: m[i] for i, a in self._live}
        if self.slot_tables is not None:
            ids = [self.agent_ids[a] for a in self.agents]
            if not ids:
                return {}
            feats, _ = slot_features(self.slot_tables, b, ids, t)
            return dict(zip(self.agents, feats))
        out = {}
        for a in self.agents:
            nodes, edges, links = observe.graph_observation(self.tab, b, t, self.agent_ids[a])
            out[a] = spaces.GraphInstance(nodes, edges, links)
        return out

    def action_mask(self, i):
        """int8 mask of robot ``i``'s valid actions from the vertex it last reached (a row of
        a table shared by every step: read it, do not change it)."""
        return self._masks[self.board.current[i]]

    def metrics(self, avg=None):
        """The monitor's figures now: instantaneous average and worst idleness (s), visits,
        complete patrol cycles, interferences; ``stats`` (the monitor's final statistics,
        as a graph-mode run's info.csv has them) once the episode is over. ``avg``: the
        average idleness now, if the caller has it."""
        mon, t = self.sim.monitor, self.sim.t
        lv = mon.last_visit
        if avg is None:
            avg = t - sum(lv) / len(lv)
        out = {"time": t, "avg_idleness": avg, "max_idleness": t - min(lv),
               "visits": mon.n_samples, "cycles": mon.cycles,
               "interferences": mon.interferences}
        if self._over and getattr(self, "final_stats", None) is not None:
            s = self.final_stats
            out["stats"] = {k: getattr(s, k) for k in s.__dataclass_fields__
                            if k != "per_vertex"}
        return out

    def _infos(self, dt):
        t = self.sim.t
        metrics = self.metrics(self._prev_avg)
        ready = self._ready
        current, masks = self.board.current, self._masks
        return {a: {"ready": i in ready, "dt": dt, "time": t, "vertex": current[i],
                    "action_mask": masks[current[i]], "metrics": metrics}
                for i, a in self._live}

    def state(self):
        """The global state for centralised critics (observe.state_vector)."""
        sim = self.sim
        pos = [sim.true_position(k) for k in range(self.opt.robots)]
        alive = [not r.core.failed for r in sim.robots]
        return observe.state_vector(self.tab, sim.monitor.last_visit, sim.t, pos, alive,
                                    self._ready_vector())

    def render(self):
        """An RGB image (H, W, 3) uint8 of the map, the graph coloured by true idleness and
        the robots; None (with a warning) without ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            warnings.warn("render() without render_mode='rgb_array': nothing drawn")
            return None
        return draw_frame(self)

    def close(self):
        if self._tmp:
            shutil.rmtree(self._tmp, ignore_errors=True)
