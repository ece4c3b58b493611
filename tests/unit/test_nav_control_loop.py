"""move_base's goal execution as a generator of waits, and its two drivers: actionlib's
execute thread (a thread per robot) and the ControlLoop that runs the goals of all robots of
a nav_host in one thread. Driven with stand-ins, without a ROS master."""
import concurrent.futures
import threading

import pytest

rospy = pytest.importorskip("rospy", reason="rospy (Debian: python3-rospy) missing")
from move_base_msgs.msg import MoveBaseGoal  # noqa: E402

from spqrel_nav_lite import move_base_goal  # noqa: E402
from spqrel_nav_lite.control_loop import ControlLoop  # noqa: E402
from spqrel_nav_lite.goal_waits import NextCycle, PlanDone, Rate, SleepUntil  # noqa: E402
from spqrel_nav_lite.move_base_goal import GoalExecution  # noqa: E402


class Clock:
    def __init__(self, t=0.0):
        self.t = t

    def __call__(self):
        return self.t


@pytest.fixture
def clock(monkeypatch):
    c = Clock()
    monkeypatch.setattr(rospy, "get_time", c)
    return c


def test_rate_keeps_rospy_rate_schedule(clock):
    """The same wake-up times as rospy.Rate.sleep: one period after the previous wake-up,
    restarted from now when more than two periods behind or when time went backwards."""
    rate = Rate(10.0)
    assert rate.sleep().until == pytest.approx(0.1)
    clock.t = 0.1
    assert rate.sleep().until == pytest.approx(0.2)
    clock.t = 0.55                         # 0.25 s late: more than two periods
    late = rate.sleep()
    assert late.until == pytest.approx(0.3) and late.ready(None)    # no wait at all
    assert rate.sleep().until == pytest.approx(0.65)                 # restarted from 0.55
    clock.t = 0.2                          # time went backwards (a restarted simulator)
    assert rate.sleep().until == pytest.approx(0.3)


class Node:
    """A robot with odometry stamps; NextCycle asks it whether a cycle is due."""

    def __init__(self):
        self.latest = None

    def cycle_due(self, period, used_stamp):
        return self.latest is not None and used_stamp is not None and \
            self.latest >= used_stamp + 0.75 * period


def test_next_cycle_waits_for_fresh_odometry_or_its_deadline(clock):
    node = Node()
    clock.t = 10.0
    wait = NextCycle(0.1, used_stamp=10.0)
    assert not wait.ready(node)
    node.latest = 10.05                    # less than 3/4 of a period newer
    assert not wait.ready(node)
    node.latest = 10.1
    assert wait.ready(node)
    node.latest = None                     # odometry stopped: the deadline, 1.5 periods
    clock.t = 10.14
    assert not wait.ready(node)
    clock.t = 10.15
    assert wait.ready(node)
    assert SleepUntil(10.2).ready(node) is False and SleepUntil(10.15).ready(node) is True


class Gate:
    """A wait the test opens."""

    def __init__(self):
        self.open = False

    def ready(self, node):
        return self.open


class Server:
    """The parts of SimpleActionServer the drivers use."""

    def __init__(self):
        self.queue = []
        self.active = False
        self.aborted = []

    def is_new_goal_available(self):
        return bool(self.queue)

    def accept_new_goal(self):
        self.active = True
        return self.queue.pop(0)

    def is_active(self):
        return self.active

    def set_aborted(self, result=None, text=""):
        self.active = False
        self.aborted.append(text)


class Robot:
    """A hosted robot whose goal task records what it did and waits at gates."""

    robot_ns = "/robot_0/"

    def stop(self):
        self.log.append(("stop",))

    def __init__(self, gates=2, finish=True):
        self.server = Server()
        self.log = []
        self.gates = [Gate() for _ in range(gates)]
        self.finish = finish

    def goal_task(self, goal):
        self.log.append(("start", goal))
        try:
            for k, gate in enumerate(self.gates):
                yield gate
                self.log.append(("cycle", goal, k))
        except rospy.ROSInterruptException:
            self.log.append(("interrupted", goal))
            self.server.set_aborted(None, "navigation shutting down")
            return
        if self.finish:
            self.server.active = False          # a terminal state, as run_goal sets
        self.log.append(("end", goal))


def test_control_loop_steps_a_goal_only_when_its_wait_is_over():
    robot = Robot()
    loop = ControlLoop()
    loop.add(robot)
    ControlLoop._step(robot)
    assert robot.log == []                       # no goal: nothing to do
    robot.server.queue.append("g1")
    ControlLoop._step(robot)
    assert robot.log == [("start", "g1")]        # accepted, run to its first wait
    ControlLoop._step(robot)
    assert robot.log == [("start", "g1")]        # the wait is not over
    robot.gates[0].open = True
    ControlLoop._step(robot)
    assert robot.log[-1] == ("cycle", "g1", 0)
    robot.gates[1].open = True
    ControlLoop._step(robot)
    assert robot.log[-1] == ("end", "g1") and robot._task is None
    assert robot.server.aborted == []            # it set its terminal state itself
    robot.server.queue.append("g2")              # the next goal starts at the next step
    robot.gates = [Gate()]
    ControlLoop._step(robot)
    assert robot.log[-1] == ("start", "g2")


def test_a_goal_that_ends_without_a_result_is_aborted_as_actionlib_does():
    robot = Robot(gates=0, finish=False)
    loop = ControlLoop()
    loop.add(robot)
    robot.server.queue.append("g")
    ControlLoop._step(robot)
    assert robot.log == [("start", "g"), ("end", "g"), ("stop",)]
    assert robot.server.aborted == ["goal ended without a result"] and not robot.server.active


def test_the_loop_thread_runs_many_robots_and_interrupts_their_goals_at_shutdown():
    stop = threading.Event()
    loop = ControlLoop(idle=0.01, is_shutdown=stop.is_set)
    robots = [Robot() for _ in range(3)]
    for r in robots:
        loop.add(r)
    loop.start()
    for k, r in enumerate(robots):
        r.server.queue.append(f"g{k}")
    loop.wake()
    robots[1].gates[0].open = robots[1].gates[1].open = True
    for _ in range(500):                      # each robot started; robot 1 finished
        if all(r.log for r in robots) and robots[1].log[-1] == ("end", "g1"):
            break
        stop.wait(0.01)
    stop.set()
    loop.join(10.0)
    assert robots[1].log == [("start", "g1"), ("cycle", "g1", 0), ("cycle", "g1", 1),
                             ("end", "g1")]
    for k in (0, 2):                          # still waiting at shutdown: interrupted
        assert robots[k].log == [("start", f"g{k}"), ("interrupted", f"g{k}")]
        assert robots[k].server.aborted == ["navigation shutting down"]


def test_an_error_in_one_robot_aborts_its_goal_and_the_loop_goes_on():
    stop = threading.Event()
    loop = ControlLoop(idle=0.01, is_shutdown=stop.is_set)
    bad, good = Robot(), Robot(gates=0)

    def broken(goal):
        raise RuntimeError("bug")
        yield
    bad.goal_task = broken
    for r in (bad, good):
        loop.add(r)
        r.server.queue.append("g")
    loop.start()
    loop.wake()
    for _ in range(500):
        if good.log[-1:] == [("end", "g")] and bad.server.aborted:
            break
        stop.wait(0.01)
    stop.set()
    loop.join(10.0)
    assert bad.server.aborted == ["internal error: RuntimeError('bug')"]
    assert bad.log == [("stop",)] and good.log == [("start", "g"), ("end", "g")]


class Execution(GoalExecution):
    """GoalExecution around a scripted run_goal, for the execute (thread) driver."""

    robot_ns = "/robot_0/"

    def __init__(self, interrupt_at=None):
        self.server = Server()
        self.server.active = True
        self.waits = []
        self.interrupt_at = interrupt_at
        self.stopped = 0

    def run_goal(self, goal_msg):
        for k in range(3):
            yield SleepUntil(float(k))
        return None

    def stop(self):
        self.stopped += 1


def test_execute_blocks_at_each_wait_and_ends_the_goal(monkeypatch):
    ex = Execution()
    blocked = []
    monkeypatch.setattr(SleepUntil, "block", lambda self, node: blocked.append(self.until))
    ex.execute(MoveBaseGoal())
    assert blocked == [0.0, 1.0, 2.0]
    # run_goal returned without a terminal state while the goal is active: at shutdown it
    # is aborted (end_at_shutdown), as before the generator
    assert ex.server.aborted == ["navigation shutting down"] and ex.stopped == 1


def test_execute_passes_a_shutdown_during_a_wait_to_the_goal(monkeypatch):
    ex = Execution()

    def block(self, node):
        if self.until == 1.0:
            raise rospy.ROSInterruptException("ROS shutdown request")
    monkeypatch.setattr(SleepUntil, "block", block)
    ex.execute(MoveBaseGoal())
    assert ex.server.aborted == ["navigation shutting down"]


class Planner(GoalExecution):
    """GoalExecution whose make_plan records the thread it ran in."""

    robot_ns = "/robot_0/"

    def __init__(self, control_loop, fail=False):
        self.control_loop = control_loop
        self.fail = fail
        self.threads = []

    def make_plan(self, pose, goal, **kwargs):
        self.threads.append(threading.current_thread().name)
        if self.fail:
            raise move_base_goal.PlanningError("no path")
        return [pose[:2], goal]


def test_without_a_control_loop_the_plan_is_made_in_the_calling_thread():
    node = Planner(None)
    task = node.planned((0.0, 0.0, 0.0), (1.0, 2.0))
    with pytest.raises(StopIteration) as end:
        next(task)
    assert end.value.value == [(0.0, 0.0), (1.0, 2.0)]
    assert node.threads == [threading.current_thread().name]


@pytest.mark.parametrize("fail", [False, True])
def test_the_control_loop_plans_in_its_planning_thread_and_wakes_when_done(fail):
    loop = ControlLoop(is_shutdown=lambda: True)
    node = Planner(loop, fail=fail)
    task = node.planned((0.0, 0.0, 0.0), (1.0, 2.0))
    wait = next(task)
    assert isinstance(wait, PlanDone)
    concurrent.futures.wait([wait.future], timeout=10)
    for _ in range(500):              # the done-callback sets the loop's wake-up flag
        if loop._pending:
            break
        threading.Event().wait(0.01)
    assert loop._pending and wait.ready(node)
    assert node.threads and node.threads[0].startswith("planner")
    if fail:
        with pytest.raises(move_base_goal.PlanningError):
            next(task)
    else:
        with pytest.raises(StopIteration) as end:
            next(task)
        assert end.value.value == [(0.0, 0.0), (1.0, 2.0)]
    loop._planner.shutdown()


class FirstCycle(GoalExecution):
    """GoalExecution with a known pose and a planner that records when it is asked."""

    robot_ns = "/robot_0/"
    global_frame = "map"
    frequency = 10.0
    localization_timeout = 5.0
    control_loop = None

    def __init__(self):
        self.events = []
        outer = self

        class FeedbackServer(Server):
            def is_preempt_requested(self):
                return False

            def publish_feedback(self, fb):
                p = fb.base_position.pose.position
                outer.events.append(("feedback", p.x, p.y))
        self.server = FeedbackServer()

    def pose(self):
        return (3.0, 4.0, 0.0)

    def laser(self, pose):
        self.events.append(("laser",))
        return None, False

    def make_plan(self, pose, goal, **kwargs):
        self.events.append(("plan",))
        raise move_base_goal.Aborted("stop here")


def test_a_goal_publishes_the_robot_s_pose_as_feedback_before_it_plans(clock):
    """As the stock move_base, whose every control cycle, the first included, begins with a
    feedback: an agent hears from its new goal at once (the original's agents clear their
    interference flag on a feedback and re-check it right after resending a goal)."""
    node = FirstCycle()
    goal = MoveBaseGoal()
    goal.target_pose.header.frame_id = "map"
    goal.target_pose.pose.position.x = 10.0
    with pytest.raises(move_base_goal.Aborted):
        next(node.run_goal(goal))
    assert node.events[0] == ("feedback", 3.0, 4.0)
    assert ("plan",) in node.events
