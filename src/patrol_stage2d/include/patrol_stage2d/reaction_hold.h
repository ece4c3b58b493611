// Reaction hold: the simulated clock waits for a robot's reaction to the end of its goal, so
// that a decision costs the same simulated time at every pace. Pure logic, no ROS: the loop
// and the subscribers pass sim and wall times in (docs/simulator.md, "Reaction hold").
//
// A robot awaits its reaction:
// - from a move_base result SUCCEEDED of its latest goal, once `goal_wait` +
//   `reaction_time` sim s have passed (the agent's goal wait is time it waits on purpose),
//   until a moving cmd_vel comes (the agent decided, move_base planned and drove);
// - from a new goal that did not follow an arrival (a resend after an interference pause or a
//   failure), once `reaction_time` sim s have passed, until a moving cmd_vel comes
//   (move_base planned).
// A moving command that overtakes the goal (they travel on different connections) ends the
// reaction too. move_base stops the robot just before it publishes the result, on another
// connection: so when a driven robot's command turns into a stop, the clock first waits up to
// `result_wait` wall s for a result (or another command). Without that wait, at a fast pace the
// stop was applied for a step before the result came, while at a slow pace the agent's next
// goal often replaced the stop in time and the robot drove on without stopping.
// While a robot awaits, the clock does not advance, for at most `wait` wall s per reaction
// (then the robot is released until its next goal, and a time-out is counted): an agent that
// takes longer chose to (e.g. it waits for messages), or is gone. Other results (aborted,
// preempted: the agent then waits on purpose, a back-up or an interference pause) start no
// reaction. `wait` = 0 never holds (nor waits after a stop).
#pragma once

#include <string>
#include <vector>

namespace patrol_stage2d {

class ReactionHold {
 public:
  ReactionHold(size_t robots, double reaction_time, double goal_wait, double wait, double result_wait)
      : reaction_time_(reaction_time), goal_wait_(goal_wait), wait_(wait), result_wait_(result_wait),
        robots_(robots) {}

  bool enabled() const { return wait_ > 0; }

  // A goal for robot i reached the simulator at sim time `sim`. Its first command may have
  // come first (move_base and the agent publish on different connections): a moving command
  // received since the last step then means the reaction is over.
  void on_goal(size_t i, const std::string& goal_id, double sim) {
    Robot& r = robots_[i];
    r.goal_id = goal_id;
    r.stop_at = -1;
    if (r.cmd_moving && r.cmd_at >= sim - 1e-9) {
      r.awaiting = false;
      return;
    }
    if (!r.awaiting || r.released) {
      r.awaiting = true;
      r.released = false;
      r.hold_since = -1;
      r.due = sim + reaction_time_;
    }
    r.goal_seen = true;
  }

  // A move_base result for robot i at sim time `sim`; only the success of its latest goal
  // starts a reaction (a result of an older goal is stale).
  void on_result(size_t i, const std::string& goal_id, bool succeeded, double sim) {
    Robot& r = robots_[i];
    r.stop_at = -1;
    r.ended = true;
    if (!succeeded || goal_id != r.goal_id) return;
    r.awaiting = true;
    r.goal_seen = r.released = false;
    r.hold_since = -1;
    r.due = sim + goal_wait_ + reaction_time_;
  }

  // A cmd_vel of robot i at sim time `sim` (`moving`: not a stop). A moving command ends the
  // reaction, whether its goal has come or not (it may overtake the goal). A stop does not:
  // move_base stops a robot twice at the end of a goal, and the second stop may come after
  // the agent's next goal (a new goal whose first command is a stop, a robot blocked at once,
  // is waited for until `wait`).
  void on_command(size_t i, bool moving, double sim) {
    Robot& r = robots_[i];
    bool result_came = r.awaiting && !r.goal_seen;  // the result overtook the stop
    r.stop_at = (r.cmd_moving && !moving && !result_came) ? sim : -1;
    r.stop_since = -1;
    r.cmd_moving = moving;
    r.cmd_at = sim;
    if (moving) r.ended = false;
    if (r.awaiting && moving) r.awaiting = false;
  }

  // Whether robot i's goal has ended (any result) since its last moving command: a stopped
  // robot that is not waiting for its controller.
  bool goal_ended(size_t i) const { return robots_[i].ended; }

  // Whether the clock must stand still before the step at sim time `sim`, wall time `wall`.
  bool holding(double sim, double wall) {
    bool hold = false;
    if (!enabled()) return false;
    for (Robot& r : robots_) {
      if (r.stop_at >= sim - 1e-9 && result_wait_ > 0) {  // stopped during this wait: a result may follow
        if (r.stop_since < 0) {
          r.stop_since = wall;
          ++stop_waits_;
        }
        if (wall - r.stop_since < result_wait_) {
          hold = true;
          continue;
        }
        r.stop_at = -1;
        ++stop_timeouts_;
      }
      if (!r.awaiting || r.released || sim + 1e-9 < r.due) continue;
      if (r.hold_since < 0) {
        r.hold_since = wall;
        ++holds_;
      }
      if (wall - r.hold_since >= wait_) {
        r.released = true;
        ++timeouts_;
      } else {
        hold = true;
      }
    }
    return hold;
  }

  long holds() const { return holds_; }        // reactions the clock waited for
  long timeouts() const { return timeouts_; }  // of them, released after `wait` wall s
  long stop_waits() const { return stop_waits_; }        // stops the clock waited after for a result
  long stop_timeouts() const { return stop_timeouts_; }  // of them, with no result within `result_wait`

 private:
  struct Robot {
    std::string goal_id;       // id of the latest goal seen
    bool cmd_moving = false;   // the latest cmd_vel was not a stop
    double cmd_at = -1;        // sim time the latest cmd_vel came
    double stop_at = -1;       // sim time a driven robot's command turned into a stop (< 0: none pending)
    double stop_since = -1;    // wall time the clock began to wait after that stop
    bool awaiting = false;     // a reaction is pending
    bool goal_seen = false;    // its goal has come
    bool ended = false;        // a result came after its last moving command
    bool released = false;     // waited `wait` wall s: no longer held for
    double due = 0;            // sim time from which the clock waits for it
    double hold_since = -1;    // wall time the clock began to wait for it (< 0: not yet)
  };
  double reaction_time_, goal_wait_, wait_, result_wait_;
  std::vector<Robot> robots_;
  long holds_ = 0, timeouts_ = 0, stop_waits_ = 0, stop_timeouts_ = 0;
};

}  // namespace patrol_stage2d
