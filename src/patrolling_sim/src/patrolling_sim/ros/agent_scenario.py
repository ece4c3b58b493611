"""The scenario of one ROS agent: its communication model and its scheduled failures
(docs/scenarios.md, "ROS mode").

Communication: the agent core applies the model (:mod:`patrolling_sim.scenarios.comm`) where
a message is *received* (on ROS a broadcast is one publish, so per-link decisions belong to
the receiver); this module reads ``/comm_model`` and hands the core the model's spec (seeded by
the core from the agent's own seed, i.e. from the run's seed), for the range model the
occupancy map and the robots' true positions.

Failures: ``/attrition`` is the run's explicit schedule (the runner drew the random model
already); the agent arms its own entries when GO arrives, against the GO time the monitor
sets in ``/go_time``. At a failure the core stops (goal cancelled, ``[id,13,0]`` on
``/results``, silent afterwards), a zero twist stops the base where it is (the simulator
keeps it there as an obstacle), and no pose goes out on ``/positions`` until the repair
(``[id,13,1]``, patrolling resumes).

Counters (the core's link decisions as receiver: sent, delivered, lost, ...) are published
on the parameter ``/scenario_counters/robot_<i>`` every 2 s of wall time, at the failure
and at END, for the monitor's ``<prefix>_scenario.yaml``.
"""
import threading
import time

import rospy

from patrolling_sim.model import map_bundle
from patrolling_sim.agent.core import END, GO, MONITOR_ID
from patrolling_sim.common.protocol import MSG_INIT
from patrolling_sim.scenarios.attrition import parse_attrition
from patrolling_sim.scenarios.comm import parse_comm
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.scenarios.scenario import is_perfect
from patrolling_sim.ros.agent_params import AgentError

COUNTERS_PERIOD = 2.0          # wall s between two counter updates
COUNTERS_PARAM = "/scenario_counters/robot_{}"


class AgentScenario:
    """Communication model and failure schedule of robot ``robot_id``, read from the global
    parameters. :meth:`core_kwargs` go to ``build_agent``; :meth:`attach` then binds the
    agent (a PatrolAgent)."""

    def __init__(self, map_arg, robot_id, team_size, initial_pos=()):
        self.id = int(robot_id)
        flat = [float(v) for v in initial_pos]
        self.initial = {i: (flat[2 * i], flat[2 * i + 1]) for i in range(len(flat) // 2)}
        self.spec = str(rospy.get_param("/comm_model", "perfect") or "perfect")
        try:
            model = parse_comm(self.spec, what="/comm_model")
            self.occupancy = None
            if model.name == "range":
                self.occupancy = map_bundle.load_map_bundle(map_arg)[0]
            schedule = parse_attrition(str(rospy.get_param("/attrition", "none") or "none"),
                                       team_size, what="/attrition")
        except PatrolInputError as e:
            raise AgentError(str(e))
        self.described = model.describe()
        self.comm_active = not is_perfect(self.spec)
        self.any_failure = bool(schedule)
        self.schedule = [f for f in schedule if f.robot == self.id]
        self.active = self.comm_active or self.any_failure
        self.agent = None
        self.go_time = None

    def core_kwargs(self):
        """Extra ``build_agent`` arguments: none without a scenario (the original's agent)."""
        if not self.active:
            return {}
        return {"comm": self.spec, "occupancy": self.occupancy,
                "silence_check": self.any_failure, "positions": self.position}

    def position(self, robot):
        """A robot's true position for the range model: its last pose heard on
        ``/positions`` before the model (own: the navigation feedback), else where it
        started (``/initial_pos``) -- so a link is judged from the first message on."""
        core = self.agent.core if self.agent is not None else None
        if core is not None:
            p = core.own_pos if robot == self.id else core.true_pos.get(robot)
            if p is not None:
                return p
        return self.initial.get(robot)

    def attach(self, agent):
        self.agent = agent
        if self.active:
            rospy.loginfo("robot %d: scenario comm %s, failures at %s", self.id, self.described,
                          ", ".join(f"{f.t:g} s" + (f" (back at {f.back:g} s)" if f.repair
                                                    else "") for f in self.schedule)
                          or "none")
            threading.Thread(target=self._counters_loop, daemon=True,
                             name=f"counters_robot_{self.id}").start()

    @property
    def failed(self):
        return bool(self.agent is not None and getattr(self.agent.core, "failed", False))

    def on_results(self, data):
        """Watch the monitor's GO (arm the failures) and END (last counters)."""
        if len(data) >= 3 and data[0] == MONITOR_ID and data[1] == MSG_INIT:
            if data[2] == GO and self.go_time is None:
                self._arm(rospy.get_time())
            elif data[2] == END:
                self.publish_counters()

    def may_publish(self):
        """False while failed: a failed robot sends nothing (no pose either)."""
        return not self.failed

    # -- failures -------------------------------------------------------------------------
    def _arm(self, now):
        """GO: arm this robot's failures and repairs against the monitor's GO time."""
        go = rospy.get_param("/go_time", None) if self.schedule else None
        try:
            self.go_time = float(go) if go is not None else now
        except (TypeError, ValueError):
            self.go_time = now
        for f in self.schedule:
            self.agent.call_later(self.go_time + f.t - now, self.fail)
            if f.back is not None:
                self.agent.call_later(self.go_time + f.back - now, self.repair)

    def fail(self):
        """The scheduled failure: stop where it stands, silent until repaired."""
        core = self.agent.core
        if self.failed or core.phase == "ended":
            return
        rospy.logwarn("robot %d: scheduled failure at %.1f s after GO", self.id,
                      rospy.get_time() - self.go_time)
        core.fail()
        self.agent.stop_base()
        self.publish_counters()

    def repair(self):
        """Back after the repair time: the core resumes patrolling."""
        core = self.agent.core
        if not self.failed or core.phase == "ended":
            return
        rospy.logwarn("robot %d: repaired at %.1f s after GO", self.id,
                      rospy.get_time() - self.go_time)
        core.repair()

    # -- counters -------------------------------------------------------------------------
    def publish_counters(self):
        if not self.active or self.agent is None:
            return
        try:
            counters = {k: int(v) for k, v in self.agent.core.comm_counters().items()}
            rospy.set_param(COUNTERS_PARAM.format(self.id), counters)
        except Exception as e:      # master gone at shutdown: the last periodic values stay
            rospy.logdebug("robot %d: counters not published: %s", self.id, e)

    def _counters_loop(self):
        while not rospy.is_shutdown() and self.agent.core.phase != "ended":
            self.publish_counters()
            time.sleep(COUNTERS_PERIOD)
