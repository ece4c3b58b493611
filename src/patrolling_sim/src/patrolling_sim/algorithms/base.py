"""The strategy base class every patrolling algorithm derives from, and the driver
protocol through which it acts on the world.

A *strategy* holds one robot's knowledge (graph, idleness tables, what it heard from
teammates) and makes that robot's decisions. It never talks to ROS or to a simulator
directly: everything goes through its *driver*, the robot's life cycle
(:class:`patrolling_sim.agent.core.PatrolAgentCore`), which is the same object in the ROS
PatrolAgent node and in the graph-level simulator.

Hooks, in the order the life cycle calls them (``docs/protocol.md``, section 3)::

    s = Strategy(ctx)                      # ctx: StrategyContext (graph, ids, rng, params)
    s.start(start_vertex, now)             # once, at the end of the start delay after GO
    v = s.next_vertex(now)                 # decide the first goal
    ...life cycle reports [id,11,start_vertex] on /results...
    s.send_results(now)                    # share: the algorithm's own message, if any
    ...goal v sent; the robot travels, arrives, waits /goal_reached_wait...
    s.on_arrival(v, now)                   # tables updated with the visit (no messages)
    v = s.next_vertex(now)                 # decide
    ...life cycle reports [id,11,v]...
    s.send_results(now)                    # share
    ...goal v sent...
    s.on_message(data, now)                # any time after GO: a teammate's message (>= 30)
    s.on_goal_failed(v, now) -> vertex     # navigation failed on v 4 times: choose another

``next_vertex`` may return None ("not decided yet", e.g. waiting for an auction): the life
cycle asks again every 0.5 s, and the report, ``send_results`` and the goal wait for the
decision. ``driver.redirect(v)`` abandons the current goal for v (honoured while moving,
paused, backing up or deciding; dropped during the goal wait).

Time ``now`` is simulated seconds (ROS time in ROS mode). Decisions must depend only on
the strategy's own state, its inputs and ``ctx.rng`` (a seeded ``random.Random``), so that
graph mode is deterministic for a given seed.
"""
import random
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple

from patrolling_sim.model.graph import PatrolGraph

from patrolling_sim.common.protocol import MSG_ROBOT_STATUS
from patrolling_sim.algorithms import wallclock
#: ``[i, 13, 0]`` robot i failed, ``[i, 13, 1]`` it is back (docs/scenarios.md)
MSG_FAILURE = MSG_ROBOT_STATUS


class Driver:
    """What a strategy may ask of the world. Implemented by the life cycle
    (:class:`patrolling_sim.agent.core.PatrolAgentCore`) in both modes; tests use fakes."""

    def now(self) -> float:
        """Current time (s)."""
        raise NotImplementedError

    def send(self, data: List[int]) -> None:
        """Broadcast an algorithm message ``[own_id, type, ...]`` on /results. The driver
        applies the communication delay and loss (``docs/protocol.md`` section 6); payloads
        must fit int16."""
        raise NotImplementedError

    def call_later(self, delay: float, fn: Callable[[], None]) -> None:
        """Run ``fn()`` after ``delay`` seconds without blocking (e.g. an auction deadline)."""
        raise NotImplementedError

    def redirect(self, vertex: int) -> None:
        """Abandon the current goal and head to ``vertex`` instead (DTAG's conflict rule)."""
        raise NotImplementedError


@dataclass
class StrategyContext:
    """Everything a strategy is constructed from.

    Attributes:
        graph: the patrol graph (pixel costs for decisions, metre positions for motion).
        robot_id: own index 0..N-1.
        team_size: N, as given to the agent (some algorithms also learn it from messages).
        map_name: map name (selects per-map parameters, e.g. GBS's G1/G2/edge_min).
        rng: seeded random generator; the only source of randomness allowed.
        driver: the :class:`Driver`.
        params: algorithm-specific options (e.g. ``msp_route`` for MSP, DTA params).
        start_position: the robot's (x, y) in metres at start (DTAG's "origin").
    """
    graph: PatrolGraph
    robot_id: int
    team_size: int
    map_name: str
    rng: random.Random
    driver: Driver
    params: Dict[str, Any] = field(default_factory=dict)
    start_position: Optional[tuple] = None


class PatrolStrategy:
    """Base class. Subclasses set ``name`` (the original's short name), implement
    :meth:`choose_next` and optionally the hooks. See the module docstring."""

    #: short name used on the command line and in result paths, e.g. "CR"
    name = None
    #: value written to /algorithm_params and info.csv ("" if none)
    algorithm_params = ""
    #: default s without a message from a teammate before :meth:`on_teammate_silent`
    TEAMMATE_TIMEOUT = 120.0
    #: True: runs are told apart by :attr:`algorithm_params` (e.g. a policy file's label),
    #: so reports show ``NAME params`` (:func:`display_name`)
    params_in_label = False

    @classmethod
    def check_params(cls, params: Dict[str, Any]) -> None:
        """Check the algorithm's ``params`` (e.g. files it reads) before anything starts:
        graph mode, the ROS runner and campaigns call it when they validate a run's
        configuration. Raises PatrolInputError with one line. Default: nothing to check."""

    @classmethod
    def content_params(cls, params: Dict[str, Any]) -> Dict[str, str]:
        """The files the algorithm reads, named by their content: {param: identity} for the
        ``params`` (checked by :meth:`check_params`) that name files, e.g. a policy file's
        ``stem@sha8``. Campaigns key a run with these identities instead of the paths, so
        a changed file at the same path makes a new run. Default: none ({})."""
        return {}

    #: the time, on the driver's clock, of the agent's clock zero: the original's agents take
    #: every vertex as last visited then (:meth:`start`). 0 in ROS mode, where the clock starts
    #: with the simulator, before GO; graph mode's GO is t = 0 and it sets ``-go_time``
    clock_zero = 0.0

    def __init__(self, ctx: StrategyContext):
        self.ctx = ctx
        self.graph = ctx.graph
        self.id = ctx.robot_id
        self.rng = ctx.rng
        self.driver = ctx.driver
        #: the draws the original makes right after ``srand(time(NULL))`` (RAND's neighbour,
        #: the ties of CR, HCR, HPCC, GBS and SEBS): ``rng``, or with the ``original_draws_*``
        #: params the original's wall-clock draws, emulated (:mod:`.wallclock`)
        self.tie_rng = wallclock.from_params(ctx.params, ctx.driver) or ctx.rng
        n = ctx.graph.n
        self.current = None           # vertex the robot stands on / last reached
        self.next = None              # vertex it is heading to
        self.last_visit = [0.0] * n   # time of the last visit known to this robot
        self.idleness = [0.0] * n     # idleness table, refreshed on events
        #: s of silence after which a teammate is given up (param ``teammate_timeout``)
        self.teammate_timeout = float(ctx.params.get("teammate_timeout",
                                                     self.TEAMMATE_TIMEOUT))

    # -- life cycle -------------------------------------------------------------------
    def prepare(self, start_vertex: int) -> None:
        """Called once before GO, when the robot becomes ready and before it announces
        itself: the place for set-up work that depends only on the graph, the parameters and
        the start vertex (a route, a partition), as the original's agents do it in their
        init, before they wait for GO. In ROS mode the clock runs while an agent computes,
        so work done in :meth:`start` instead would hold the robot on its start vertex for
        simulated time (at x30, 0.1 s of CPU costs 3 s). Must not draw from ``rng`` (graph
        mode and ROS mode call it at different moments). Default: nothing."""

    def start(self, start_vertex: int, now: float) -> None:
        """Called once at GO, before the first decision. Default, as the original's agent:
        every vertex was last visited at the clock's zero (:attr:`clock_zero`), the start
        vertex 0.1 s later (so that it looks visited), and the idleness table is all zero:
        the original does not refresh it before its first decision, so the first choice of an
        idleness-driven rule is a tie among the neighbours (broken uniformly with ``rng``),
        HCR's and HPCC's the nearest candidate. A vertex the robot has not visited since
        keeps the idleness of the clock, which ran before GO. ``now`` is not used by the
        default."""
        self.current = start_vertex
        self.last_visit = [self.clock_zero] * self.graph.n
        self.last_visit[start_vertex] = self.clock_zero + 0.1
        self.idleness = [0.0] * self.graph.n

    def next_vertex(self, now: float) -> int:
        """Decide the next goal from ``self.current``; stores it in ``self.next``."""
        self.next = self.choose_next(now)
        return self.next

    def on_arrival(self, vertex: int, now: float) -> None:
        """The robot reached ``vertex`` (after the goal wait). Default: record the visit and
        refresh the whole idleness table (the original's update_idleness). Messages are sent
        in :meth:`send_results`, never here."""
        self.current = vertex
        self.last_visit[vertex] = now
        self.update_idleness(now)

    def send_results(self, now: float) -> None:
        """Called after every visit report ``[id,11,v]`` (also the first one, for the start
        vertex), before the next goal is sent: the place where an algorithm broadcasts what
        it shares with its teammates (the original's order: update, decide, report, share,
        go). Default: nothing."""

    def on_message(self, data: Tuple[int, ...], now: float) -> None:
        """A /results message from another robot (own messages are filtered out by the
        driver), as a tuple: one message may reach every teammate as the same object.
        Default: ignore."""

    def on_teammate_silent(self, robot_id: int, now: float) -> None:
        """Teammate ``robot_id`` has sent nothing for ``teammate_timeout`` s (it may have
        failed, docs/scenarios.md). Only called when the run has an attrition scenario.
        Default: nothing (rules without teammate state keep their rule)."""

    def on_repair(self, now: float) -> None:
        """The robot is back after a failure (docs/scenarios.md), just before it decides
        again. Every timer the strategy had asked for was void while it was down: a strategy
        that waits on one (DTAP's auction) restarts it here. Default: nothing."""

    def on_goal_failed(self, vertex: int, now: float) -> int:
        """Navigation gave up on ``vertex`` after the resends. Default: as the original's
        onGoalNotComplete -- recompute; while that gives the failed vertex again, draw a
        random neighbour of the current vertex (at most 10 draws); if the result is still
        the failed vertex and that is the current vertex, draw random vertices until it
        differs. Returns the new goal."""
        v = self.choose_next(now)
        nbrs = self.graph.neighbor_ids(self.current)
        draws = 0
        while v == vertex and draws < 10 and nbrs:
            v = self.rng.choice(nbrs)
            draws += 1
        while v == vertex and v == self.current and self.graph.n > 1:
            v = self.rng.randrange(self.graph.n)
        self.next = v
        return v

    # -- helpers ----------------------------------------------------------------------
    def choose_next(self, now: float) -> int:
        raise NotImplementedError

    def update_idleness(self, now: float) -> None:
        self.idleness[:] = [now - t for t in self.last_visit]

    def send(self, *payload: int) -> None:
        """Send ``[own_id, *payload]`` through the driver."""
        self.driver.send([self.id, *[int(x) for x in payload]])


def argmax_random(items, key, rng, eps=1e-9):
    """The item maximising ``key``; ties (within ``eps``) broken uniformly with ``rng``."""
    items = list(items)
    vals = [key(x) for x in items]
    best = max(vals)
    ties = [x for x, v in zip(items, vals) if v >= best - eps]
    return ties[0] if len(ties) == 1 else rng.choice(ties)


#: short name -> strategy class; filled by :func:`register`
REGISTRY: Dict[str, type] = {}


def register(cls):
    """Class decorator: ``@register`` adds a strategy to :data:`REGISTRY` under ``cls.name``."""
    if not cls.name:
        raise ValueError(f"{cls.__name__} has no name")
    REGISTRY[cls.name] = cls
    return cls


def display_name(name: str, params: str) -> str:
    """How reports name an algorithm's runs: ``name``, or ``"name params"`` for a registered
    strategy with :attr:`PatrolStrategy.params_in_label` and non-empty ``params``."""
    cls = REGISTRY.get(name)
    if cls is not None and cls.params_in_label and params and str(params) != "nan":
        return f"{name} {params}"
    return name


def names():
    """Registered short names, sorted."""
    return sorted(REGISTRY)


def create(name: str, ctx: StrategyContext) -> PatrolStrategy:
    """Instantiate the strategy registered as ``name``.

    Raises:
        KeyError: unknown name (the message lists the known ones).
    """
    try:
        cls = REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown algorithm '{name}' (known: {', '.join(names())})") from None
    return cls(ctx)
