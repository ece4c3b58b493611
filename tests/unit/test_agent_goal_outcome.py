"""The PatrolAgent node's goal outcomes (patrolling_sim.ros.agent) against actionlib's real
client state machine, without a ROS master: actionlib reports an outcome holding the goal's
mutex while another thread, holding the node's lock, cancels that goal (an interference, or
a new goal replacing it). Before the outcome thread, the two waited for each other for good:
in a 16-robot run one agent froze at an interference and never moved again."""
import threading

import pytest

actionlib_client = pytest.importorskip("actionlib.action_client",
                                       reason="actionlib (Debian: python3-actionlib) missing")
from actionlib_msgs.msg import GoalStatus  # noqa: E402
from move_base_msgs.msg import MoveBaseActionGoal, MoveBaseActionResult  # noqa: E402

from patrolling_sim.ros.agent import PatrolAgent  # noqa: E402

#: generous: the threads below need milliseconds; only a deadlock takes longer
DEADLOCK = 30.0


class CoreStub:
    seq, target = 1, 7

    def __init__(self):
        self.results = []
        self.done = threading.Event()

    def on_goal_result(self, seq, ok):
        self.results.append((seq, ok))
        self.done.set()


def _node():
    node = PatrolAgent.__new__(PatrolAgent)      # the glue only: no graph, no rospy node
    node.id = 3
    node.lock = threading.RLock()
    node.core = CoreStub()
    node._start_outcome_thread()
    return node


def _goal(node, seq, entered, goal_id="goal-1"):
    goal = MoveBaseActionGoal()
    goal.goal_id.id = goal_id

    def transition_cb(gh):
        entered.set()
        node._on_transition(gh, seq)
    csm = actionlib_client.CommStateMachine(goal, transition_cb, None, lambda g: None,
                                            lambda cancel: None)
    return csm, actionlib_client.ClientGoalHandle(csm)


def _result(status, goal_id="goal-1"):
    result = MoveBaseActionResult()
    result.status.goal_id.id = goal_id
    result.status.status = status
    return result


def test_an_outcome_while_the_goal_is_cancelled_under_the_lock_does_not_deadlock():
    node = _node()
    entered = threading.Event()
    csm, gh = _goal(node, 1, entered)
    node.gh = gh
    result = _result(GoalStatus.SUCCEEDED)
    has_lock = threading.Event()

    def canceller():                     # e.g. the /positions callback at an interference
        with node.lock:
            has_lock.set()
            entered.wait(DEADLOCK)       # actionlib is inside the callback, its mutex held
            gh.cancel()                  # waits for that mutex

    def reporter():                      # actionlib's result subscriber
        has_lock.wait(DEADLOCK)
        csm.update_result(result)

    threads = [threading.Thread(target=f, daemon=True) for f in (canceller, reporter)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(DEADLOCK)
    assert not any(t.is_alive() for t in threads), "deadlock: cancel and outcome wait " \
                                                   "for each other"
    assert node.core.done.wait(DEADLOCK)
    assert node.core.results == [(1, True)]
    assert node.gh is None


def test_the_outcome_of_a_replaced_goal_is_ignored_and_a_failure_reported():
    node = _node()
    node.core.seq = 2                              # goal 1 was replaced by goal 2
    old_csm, _ = _goal(node, 1, threading.Event(), "goal-1")
    csm, gh = _goal(node, 2, threading.Event(), "goal-2")
    node.gh = gh
    old_csm.update_result(_result(GoalStatus.SUCCEEDED, "goal-1"))
    csm.update_result(_result(GoalStatus.ABORTED, "goal-2"))
    # outcomes are handled in order: once goal 2's is in, goal 1's was seen and ignored
    assert node.core.done.wait(DEADLOCK)
    assert node.core.results == [(2, False)]
    assert node.gh is None
