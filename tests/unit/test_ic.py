"""IC, the Idleness Coordinator (docs/algorithms/IC.md): the host sends each requester to
the idlest vertex nobody else is heading to, in request order, never the same vertex to two
robots at once; a requester waits, then chooses alone; the next lowest id takes over a
silent host and a repaired robot 0 hosts again."""
import pytest

from patrolling_sim.algorithms.ic import IdlenessCoordinator
from patrolling_sim.algorithms.testing import RecordingDriver, deliver, make_strategy
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.algorithms.testing import graph_from


#: a ring of six vertices, cost 10 per edge
RING = graph_from({v: (10 * v, 10) for v in range(6)}, {(v, (v + 1) % 6): 10 for v in range(6)})


class WaitingDriver(RecordingDriver):
    """A recording driver whose life cycle waits for a pending decision, as the real one."""
    accepts_pending_decision = True


def coordinated(n=3):
    out = [make_strategy("IC", graph=RING, robot_id=i, team_size=n, seed=i,
                         driver=WaitingDriver()) for i in range(n)]
    for i, (s, _) in enumerate(out):
        s.start(i, 0.0)
    return [s for s, _ in out], [d for _, d in out]


def test_host_sends_requesters_to_the_idlest_free_vertex_in_request_order():
    (host, r1, r2), (dh, d1, d2) = coordinated()
    assert host.host == 0 and r1.host == 0
    # the host's table: vertex 4 idlest, then 3, then 5 (last visits at 1, 2, 3 s)
    host.last_visit[:] = [50.0, 40.0, 30.0, 2.0, 1.0, 3.0]
    assert r1.next_vertex(60.0) is None and r2.next_vertex(60.0) is None   # waiting
    assert d1.sent == [[1, 54, 1, 1]] and d2.sent == [[2, 54, 2, 1]]
    deliver(d1.sent + d2.sent, [host], 60.0)
    # robot 1 asked first: 4; robot 2 next: 3 -- not 4 again; distance plays no part
    assert dh.sent == [[0, 55, 1, 4], [0, 55, 2, 3]]
    assert host.assigned == {1: 4, 2: 3}
    # the answer releases the waiting robot at once, along the shortest path
    deliver(dh.sent, [r1, r2], 60.5)
    assert d1.redirects == [2] and r1.path == [3, 4]
    assert d2.redirects == [3] and r2.path == []
    # the host's own decision skips the vertices its teammates are heading to
    goal = host.assign(0, 0, 61.0)
    assert goal == 5


def test_without_an_answer_the_requester_chooses_alone_and_says_so():
    (host, r1, _), (_, d1, _) = coordinated()
    r1.last_visit[:] = [9.0, 9.0, 9.0, 9.0, 0.5, 9.0]
    assert r1.next_vertex(10.0) is None
    assert r1.next_vertex(14.9) is None
    step = r1.next_vertex(15.0)                 # ic_timeout = 5 s
    assert r1.fallbacks == 1 and r1.assigned[1] == 4 and step == 2
    r1.send_results(15.0)
    assert d1.sent[-1] == [1, 55, 1, 4]
    # a late answer is ignored: the robot is no longer waiting
    r1.on_message((0, 55, 1, 5), 16.0)
    assert d1.redirects == [] and r1.assigned[1] == 5


def test_the_next_lowest_id_takes_over_a_silent_host():
    (host, r1, r2), (_, d1, d2) = coordinated()
    for s in (r1, r2):
        s.on_teammate_silent(0, 130.0)
    assert r1.host == 1 and r2.host == 1
    assert r2.next_vertex(131.0) is None
    deliver(d2.sent, [r1], 131.0)
    assert d1.sent[-1][:3] == [1, 55, 2]
    host.send(54, 0, 0)                         # robot 0 heard again: host again
    deliver(host.driver.sent, [r1, r2], 140.0)
    assert r1.host == 0 and r2.host == 0


def run(tmp_path, monkeypatch, **kw):
    """A graph-mode IC run; returns (sim, visits, assignments): every (time, host, robot,
    goal) message 55 the hosting robot sent."""
    sent = []
    original = IdlenessCoordinator.send

    def spy(self, *payload):
        if payload[0] == 55 and self.host == self.id:
            sent.append((self.driver.now(), self.id) + tuple(payload[1:]))
        original(self, *payload)
    monkeypatch.setattr(IdlenessCoordinator, "send", spy)
    kw.setdefault("map", "grid")
    kw.setdefault("params", {"teammate_timeout": 60.0})
    sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), alg="IC", **kw))
    sim.run()
    return sim, read_visits(sim.prefix + "_visits.csv"), sent


def never_twice(assignments):
    """Replays one host's assignments: none is a vertex another robot is heading to."""
    heading = {}
    for _, _, robot, goal in assignments:
        others = {g for r, g in heading.items() if r != robot}
        assert goal not in others, (robot, goal, heading)
        heading[robot] = goal
    return heading


@pytest.mark.parametrize("comm", ["perfect", "perfect;delay=const:0.5"])
def test_graph_mode_the_coordinator_never_assigns_a_vertex_twice(tmp_path, monkeypatch, comm):
    sim, visits, sent = run(tmp_path, monkeypatch, robots=6, duration=1200, seed=3, comm=comm)
    assert sim.termination == "TIMEOUT"
    assert len(sent) > 300 and {h for _, h, _, _ in sent} == {0}
    never_twice(sent)
    assert all(r.core.strategy.fallbacks == 0 for r in sim.robots)
    assert {v for t, _, v in visits if t > 600.0} == set(range(sim.g.n))


def test_graph_mode_host_failure_takeover_and_return(tmp_path, monkeypatch):
    """Robot 0 (the host) fails at 400 s and is back at 800 s: robot 1 hosts once robot 0
    has been silent for 60 s, then hands back; each host never assigns a vertex twice."""
    sim, visits, sent = run(tmp_path, monkeypatch, robots=5, duration=1400, seed=1,
                            attrition="0@400+400")
    assert sim.termination == "TIMEOUT"
    by_host = {h: [a for a in sent if a[1] == h] for h in (0, 1)}
    assert by_host[1] and all(400.0 < t < 900.0 for t, *_ in by_host[1])
    assert [t for t, *_ in by_host[0] if t > 800.0]
    never_twice([a for a in by_host[0] if a[0] < 400.0])
    never_twice(by_host[1])
    assert all(r.core.strategy.host == 0 for r in sim.robots)
    assert {v for t, _, v in visits if 500.0 < t < 800.0} == set(range(sim.g.n))


def test_graph_mode_lossy_links_fall_back_and_keep_patrolling(tmp_path, monkeypatch):
    sim, visits, _ = run(tmp_path, monkeypatch, robots=4, duration=1200, seed=2,
                         comm="bernoulli:p=0.3", attrition="2@600")
    assert sim.termination == "TIMEOUT"
    assert sum(r.core.strategy.fallbacks for r in sim.robots) > 0
    assert {v for t, _, v in visits if t > 700.0} == set(range(sim.g.n))
