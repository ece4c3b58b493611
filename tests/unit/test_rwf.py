"""RWF, Reactive With Flags (docs/algorithms/RWF.md): a robot reads only the flag of the
vertex it stands on and goes to the neighbour that flag shows oldest; its flag writes, their
messages, and graph-mode runs under --attrition and --comm."""

from patrolling_sim.algorithms.msgtime import encode_time
from patrolling_sim.algorithms.rwf import FlagBoard, oldest_neighbour
from patrolling_sim.algorithms.testing import deliver, make_strategy, walk
from patrolling_sim.common.protocol import MSG_RWF_DEPART, MSG_RWF_VISIT
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.algorithms.testing import graph_from as hand_made_graph


def graph_from(vertices, edges):
    """A hand-made graph on a 400 px map (:func:`~patrolling_sim.algorithms.testing.graph_from`)."""
    return hand_made_graph(vertices, edges, size_px=400)


#: vertex 0 in the middle of 1, 2, 3; 4 joins 1 and 2 (a way round)
STAR = graph_from({0: (200, 200), 1: (100, 200), 2: (300, 200), 3: (200, 300),
                   4: (200, 100)},
                  {(0, 1): 100, (0, 2): 100, (0, 3): 100, (1, 4): 141, (2, 4): 141})


def rwf(rid=0, n=2, seed=0):
    return make_strategy("RWF", graph=STAR, robot_id=rid, team_size=n, seed=seed)


class SpyBoard(FlagBoard):
    """A board that records which vertex's flag is read."""

    def __init__(self, n):
        super().__init__(n)
        self.reads = []

    def read(self, v):
        self.reads.append(v)
        return super().read(v)


def test_reads_only_the_flag_where_it_stands():
    """Over a long walk on cumberland every decision reads one flag: the one of the vertex
    the robot stands on (the start vertex, then each vertex reached)."""
    s, d = make_strategy("RWF", "cumberland", seed=2)
    s.board = SpyBoard(s.graph.n)
    goals = walk(s, d, 7, 300)
    assert s.board.reads == [7] + goals
    assert set(goals) == set(range(s.graph.n))


def test_goes_to_the_oldest_and_ignores_every_other_flag():
    """Robot on 0 at t=100, flag of 0: 1 marked at 50, 2 at 10, 3 at 30: it takes 2 for
    every seed. Flags elsewhere (2's own flag says 2 was visited at 99) change nothing."""
    for seed in range(20):
        s, _ = rwf(seed=seed)
        s.start(4, 0.0)
        for w, t in ((1, 50.0), (2, 10.0), (3, 30.0)):
            s.on_message((1, MSG_RWF_DEPART, 0, w, encode_time(t)), 60.0)
        s.on_message((1, MSG_RWF_VISIT, 2, encode_time(99.0), 4, encode_time(90.0)), 99.0)
        assert dict(s.board.read(0)) == {1: 50.0, 2: 10.0, 3: 30.0}
        s.came_from = None
        s.on_arrival(0, 100.0)
        assert s.next_vertex(100.0) == 2
    flag = {1: 50.0, 3: 30.0}                       # 2 never marked: time 0, the oldest
    assert oldest_neighbour(flag, (1, 2, 3), None) == 2


def test_writes_on_visit_and_departure_and_their_messages():
    s, d = rwf(seed=1)
    s.start(1, 0.0)
    first = s.next_vertex(0.0)
    s.send_results(0.0)
    assert d.sent == [[0, MSG_RWF_VISIT, 1, 0, -1, 0], [0, MSG_RWF_DEPART, 1, first, 0]]
    assert dict(s.board.read(1)) == {1: 0.0, first: 0.0}
    d.sent.clear()
    s.on_arrival(first, 12.5)
    nxt = s.next_vertex(12.5)
    s.send_results(12.5)
    # at ``first``: its visit, the news from 1 (visited at 0), the departure to ``nxt``
    assert d.sent == [[0, MSG_RWF_VISIT, first, encode_time(12.5), 1, 0],
                      [0, MSG_RWF_DEPART, first, nxt, encode_time(12.5)]]
    assert dict(s.board.read(first)) == {first: 12.5, 1: 0.0, nxt: 12.5} or nxt == 1


def test_a_teammates_departure_mark_steers_the_next_robot_elsewhere():
    """Robot 0 leaves 0 for some branch; robot 1 comes to 0 from 3 later and, reading the
    flag of 0, takes neither that branch nor 3; without the message it sometimes follows."""
    followed = set()
    for seed in range(20):
        for heard in (True, False):
            a, da = rwf(rid=0, seed=seed)
            b, _ = rwf(rid=1, seed=seed)
            a.start(0, 0.0)
            va = a.next_vertex(0.3)
            a.send_results(0.3)
            b.start(3, 5.0)
            b.next_vertex(5.0)                          # 3's only neighbour: 0
            if heard:
                deliver(da.sent, [b], 0.4)
            b.on_arrival(0, 15.0)
            vb = b.next_vertex(15.0)
            if heard:
                assert vb not in (va, 3)
            else:
                followed.add(vb == va)
    assert True in followed


def test_loss_of_a_write_is_a_mark_never_seen():
    a, da = rwf(rid=0)
    b, _ = rwf(rid=1)
    a.start(0, 0.0)
    a.next_vertex(0.0)
    a.send_results(0.0)
    deliver(da.sent[:1], [b], 0.1)                  # the departure write is lost
    assert dict(b.board.read(0)) == {0: 0.0}


def test_goal_failure_and_repair_broadcast_the_new_departure():
    s, d = rwf(seed=3)
    s.start(0, 0.0)
    s.next_vertex(0.0)
    s.send_results(0.0)
    d.sent.clear()
    v = s.on_goal_failed(s.next, 40.0)
    assert d.sent == [[0, MSG_RWF_DEPART, 0, v, encode_time(40.0)]]
    d.sent.clear()
    s.on_repair(300.0)
    v = s.next_vertex(300.0)
    assert d.sent == [[0, MSG_RWF_DEPART, 0, v, encode_time(300.0)]]


def test_long_walk_messages_fit_int16():
    s, d = make_strategy("RWF", "cumberland", seed=1)
    walk(s, d, 0, 300, speed=0.2)                  # RecordingDriver refuses non-int16
    assert d.t > 3276.8 and len(d.sent) == 2 * 301


# ----------------------------------------------------------------------- graph mode
def run(tmp_path, **kw):
    kw.setdefault("map", "grid")
    sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), alg="RWF", **kw))
    sim.run()
    return sim


def visits(sim):
    from patrolling_sim.monitor.metrics import read_visits
    return read_visits(sim.prefix + "_visits.csv")


def test_graph_mode_attrition_a_failed_robot_writes_no_more(tmp_path):
    sim = run(tmp_path, robots=4, duration=1800, seed=3, attrition="2@600")
    assert sim.termination == "TIMEOUT" and sim.monitor.failures == [[2, 600.0, None]]
    assert {v for t, _, v in visits(sim) if t > 600.0} == set(range(sim.g.n))
    dead = sim.robots[2].core.strategy.board.flags
    assert max(t for f in dead for t in f.values()) <= 600.0


def test_graph_mode_comm_flags_travel_through_the_model(tmp_path):
    """Perfect links: every robot's copy of the flags is the same. No link at all: each
    robot's copy holds only flags of vertices it stood on itself."""
    perfect = run(tmp_path / "p", robots=4, duration=900, seed=1, comm="perfect")
    boards = [r.core.strategy.board.flags for r in perfect.robots]
    assert all(b == boards[0] for b in boards)
    cut = run(tmp_path / "c", robots=4, duration=900, seed=1, comm="range:r=0.001,los=false")
    assert cut.termination == "TIMEOUT"
    stood = {r: {v for _, rr, v in visits(cut) if rr == r} for r in range(4)}
    for r in range(4):
        marked = {v for v, f in enumerate(cut.robots[r].core.strategy.board.flags) if f}
        assert marked <= stood[r] | {cut.robots[r].core.start_vertex}
        assert marked != set(range(cut.g.n)) or stood[r] == set(range(cut.g.n))
