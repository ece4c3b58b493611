// Timer hold: the simulated clock stands still at a step where an agent process has a timer
// due, until the process reports that the timer fired, so that a timer's action (the end of
// a goal wait or of an interference pause, a resend) goes out at the same sim step at every
// pace. Pure logic, no ROS: the loop passes the agents' reports and the wall times in
// (docs/simulator.md, "Timer hold"; the abstract world's clock_hold.TimerReports is the
// same rule).
//
// This project's agents report on /sim_timers (patrolling_sim.ros.sim_timers), one reporter
// per agent process: [done, next, ...] says that its timers due up to sim time `done` have
// fired and that `next` is its earliest pending deadline (< 0: none). Before the step that
// would move the clock past sim time `sim`, the clock stands still while a reporter's `next`
// is at or before `sim`, for at most `wait` wall s per step; a reporter whose wait reached
// that bound is left out until it reports again (a process that ended, or one too busy to
// answer, costs one bounded wait, not one per step). The original's agents send no reports
// and are not waited for. `wait` 0 turns the hold off.
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace patrol_stage2d {

class TimerHold {
 public:
  // Throws std::invalid_argument if `wait` is negative.
  explicit TimerHold(double wait) : wait_(wait) {
    if (wait < 0) throw std::invalid_argument("~timer_wait must be >= 0");
  }

  bool enabled() const { return wait_ > 0; }

  // A report of `reporter` (the publishing node's name): `next` is its earliest pending
  // deadline (sim s, < 0: none). Its earlier deadline, if any, has fired or moved.
  void on_report(const std::string& reporter, double next) {
    if (next < 0) next_.erase(reporter);
    else next_[reporter] = next;
  }

  // Whether the clock, now at sim time `sim`, must stand still at wall time `wall` (s,
  // steady clock). The first call of a hold starts its wall-time bound; a hold ends when
  // no reporter has a deadline at or before `sim` any more, or at the bound (a time-out:
  // the reporters then due are left out until they report again).
  bool holding(double sim, double wall) {
    if (!enabled()) return false;
    std::vector<std::string> due;
    for (const auto& kv : next_)
      if (kv.second <= sim + kTolerance) due.push_back(kv.first);
    if (due.empty()) {
      since_ = -1;
      return false;
    }
    if (since_ < 0 || sim != held_sim_) {
      since_ = wall;
      held_sim_ = sim;
      ++holds_;
    }
    if (wall - since_ < wait_) return true;
    for (const std::string& r : due) next_.erase(r);
    ++timeouts_;
    since_ = -1;
    return false;
  }

  long holds() const { return holds_; }        // steps the clock waited at for timers
  long timeouts() const { return timeouts_; }  // of them, ended by the `wait` bound

 private:
  static constexpr double kTolerance = 1e-6;  // a deadline within this of the clock is due
  double wait_;
  std::map<std::string, double> next_;  // reporter -> earliest pending deadline
  double since_ = -1;                   // wall time the current hold began (< 0: none)
  double held_sim_ = -1;                // the clock reading it holds at
  long holds_ = 0, timeouts_ = 0;
};

}  // namespace patrol_stage2d
