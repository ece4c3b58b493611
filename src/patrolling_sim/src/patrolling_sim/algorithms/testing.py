"""A driver to unit-test a strategy without a world: build it, call its hooks in the life
cycle's order, and read what it sent, the timers it set and the goals it chose.

    from patrolling_sim.algorithms.testing import make_strategy, walk

    strategy, driver = make_strategy("CR", "grid", seed=3)
    goals = walk(strategy, driver, start=0, steps=100)     # the vertices it went to
    assert set(goals) == set(range(strategy.graph.n))
    driver.sent                                             # every message, in order

Time is what the test says: :func:`walk` moves the clock by travel time (path metres over
``speed``) and runs the timers that fell due; messages go nowhere unless the test delivers
them (:func:`deliver`). The full life cycle around a strategy (start delays, goal wait,
interference, message delay and loss) is graph mode:
``GraphSimulator(GraphSimConfig(...)).run(write=False)``.
"""
import random
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from patrolling_sim.algorithms.base import Driver, PatrolStrategy, StrategyContext, create
from patrolling_sim.common.paths import map_files
from patrolling_sim.model.graph import PatrolGraph, parse_graph

#: the payload range of a ``/results`` message (std_msgs/Int16MultiArray)
INT16_MIN, INT16_MAX = -32768, 32767


class RecordingDriver(Driver):
    """A :class:`~patrolling_sim.algorithms.base.Driver` that records instead of acting.

    Attributes:
        t: the current time (s), set by the test or by :func:`walk`.
        sent: every message the strategy sent, as lists of ints, in order.
        timers: ``(due time, callback)`` of the timers not yet run.
        redirects: the vertices the strategy redirected its robot to, in order.
    """
    #: decisions are taken at once (a strategy that may hold a decision, as DTAP during its
    #: auction, decides without waiting)
    accepts_pending_decision = False

    def __init__(self, t: float = 0.0):
        self.t = t
        self.sent: List[List[int]] = []
        self.timers: List[Tuple[float, Callable[[], None]]] = []
        self.redirects: List[int] = []

    def now(self) -> float:
        return self.t

    def send(self, data) -> None:
        """Record ``data``. Raises ValueError if a value does not fit the message's int16."""
        data = list(data)
        if not all(INT16_MIN <= x <= INT16_MAX for x in data):
            raise ValueError(f"message {data} does not fit in int16 values")
        self.sent.append(data)

    def call_later(self, delay: float, fn: Callable[[], None]) -> None:
        self.timers.append((self.t + delay, fn))

    def redirect(self, vertex: int) -> None:
        self.redirects.append(vertex)

    def run_due_timers(self) -> int:
        """Run, in time order, every timer due at or before :attr:`t`; returns how many."""
        due = sorted((x for x in self.timers if x[0] <= self.t), key=lambda x: x[0])
        self.timers = [x for x in self.timers if x[0] > self.t]
        for _, fn in due:
            fn()
        return len(due)


_GRAPHS: Dict[str, PatrolGraph] = {}


def graph_from(vertices: Dict[int, Tuple[float, float]], edges: Dict[Tuple[int, int], float],
               size_px: int = 100) -> PatrolGraph:
    """A hand-made patrol graph: ``vertices`` {id: (x_px, y_px)}, undirected ``edges``
    {(a, b): cost}, a ``size_px`` x ``size_px`` map at 0.1 m per pixel, origin (0, 0).
    Each vertex lists its edges in the order ``edges`` gives them."""
    nb = {v: [] for v in vertices}
    for (a, b), c in edges.items():
        nb[a].append((b, c))
        nb[b].append((a, c))
    lines = [str(len(vertices)), str(size_px), str(size_px), "0.1", "0", "0", ""]
    for v in sorted(vertices):
        x, y = vertices[v]
        lines += [str(v), str(x), str(y), str(len(nb[v]))]
        for w, c in nb[v]:
            lines += [str(w), "N", str(c)]
        lines.append("")
    return PatrolGraph(parse_graph("\n".join(lines)))


def load_graph(map_name: str) -> PatrolGraph:
    """The patrol graph of a shipped map (or a map path), loaded once per process.

    Raises:
        PatrolInputError: unknown map or unreadable graph file.
    """
    if map_name not in _GRAPHS:
        _GRAPHS[map_name] = PatrolGraph.load(map_files(map_name)[1])
    return _GRAPHS[map_name]


def make_strategy(alg: str, map_name: str = "grid", robot_id: int = 0, team_size: int = 1,
                  seed: int = 0, params: Optional[dict] = None,
                  graph: Optional[PatrolGraph] = None,
                  driver: Optional[Driver] = None) -> Tuple[PatrolStrategy, Driver]:
    """A registered strategy ``alg`` for robot ``robot_id`` of a team of ``team_size`` on
    ``map_name`` (or on ``graph``), with a :class:`RecordingDriver` unless ``driver`` is
    given; its random generator is ``random.Random(seed)``. Returns (strategy, driver).

    Raises:
        KeyError: ``alg`` is not registered.
    """
    g = graph if graph is not None else load_graph(map_name)
    d = driver if driver is not None else RecordingDriver()
    ctx = StrategyContext(g, robot_id, team_size, map_name, random.Random(seed), d,
                          dict(params or {}))
    return create(alg, ctx), d


def walk(strategy: PatrolStrategy, driver: RecordingDriver, start: int, steps: int,
         speed: float = 1.0) -> List[int]:
    """Drive one strategy alone through ``steps`` goals from vertex ``start``, as the life
    cycle does: ``start``, ``next_vertex`` and ``send_results``; then for each goal travel
    there (the clock advances by the shortest path's metres over ``speed``, due timers run),
    ``on_arrival``, and the next ``next_vertex`` and ``send_results``. Returns the goals in
    order (the decision taken after the last arrival is made but not travelled).

    Raises:
        AssertionError: the strategy chose a vertex that is not in its graph.
    """
    g = strategy.graph
    strategy.start(start, driver.t)
    goals = []
    goal = strategy.next_vertex(driver.t)
    strategy.send_results(driver.t)
    here = start
    for _ in range(steps):
        assert 0 <= goal < g.n, f"goal {goal} is not a vertex of the graph (0..{g.n - 1})"
        driver.t += g.dist[here, goal] * g.resolution / speed
        driver.run_due_timers()
        strategy.on_arrival(goal, driver.t)
        goals.append(goal)
        here = goal
        goal = strategy.next_vertex(driver.t)
        strategy.send_results(driver.t)
    return goals


def deliver(sent: Sequence[Sequence[int]], receivers: Sequence[PatrolStrategy],
            now: float) -> int:
    """Deliver every message of ``sent`` to each of ``receivers`` other than its sender (the
    first value of a message is the sender's robot id), through ``on_message``, in order.
    Returns the number of deliveries."""
    count = 0
    for data in sent:
        for r in receivers:
            if r.id != data[0]:
                r.on_message(tuple(data), now)
                count += 1
    return count
