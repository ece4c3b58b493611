// GO hold: the simulated clock stands still around the monitor's GO, so that every agent
// starts its patrol at the same sim time at every pace. Pure logic, no ROS: the loop passes
// the /results messages and the wall times in (docs/simulator.md, "GO hold"; the abstract
// world's clock_hold.GoHold is the same rule).
//
// Once all `team` robots have announced themselves ready ([id, 10, 1] on /results) the clock
// stands still until GO ([-1, 10, 100]), at most `announce_wait` wall s: the monitor sends GO
// as soon as it has every announcement and takes GO's sim time then. From the moment GO is
// seen the clock stands still for `go_wait` wall s more: GO reaches each agent on its own
// connection, and an agent that reads it a step later starts its whole patrol a step later
// (GO asks for no answer: no sign but time says that every agent has read it). A wait for GO
// that ends without GO counts as a time-out, and no other wait for it follows (the GO that
// comes later still starts its `go_wait`). Only the first GO counts. `go_wait` 0 turns the
// hold off.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace patrol_stage2d {

class GoHold {
 public:
  // Throws std::invalid_argument if a wait is negative.
  GoHold(size_t team, double go_wait, double announce_wait)
      : go_wait_(go_wait), announce_wait_(announce_wait), ready_(team, false) {
    if (go_wait < 0 || announce_wait < 0) throw std::invalid_argument("~go_wait must be >= 0");
  }

  bool enabled() const { return go_wait_ > 0; }

  // A /results message `d` seen at wall time `wall` (s, steady clock); true if it is the
  // first GO. Messages of other types, and anything after the first GO, change nothing.
  bool on_results(const std::vector<int16_t>& d, double wall) {
    if (go_seen_ || d.size() < 3 || d[1] != kInit) return false;
    if (d[0] == kMonitor && d[2] == kGo) {
      go_seen_ = true;
      awaiting_go_ = false;
      end_ = enabled() ? wall + go_wait_ : -1;
      return true;
    }
    if (d[2] != kReady || d[0] < 0 || static_cast<size_t>(d[0]) >= ready_.size() || !enabled() || awaiting_go_)
      return false;
    ready_[d[0]] = true;
    for (bool r : ready_)
      if (!r) return false;
    awaiting_go_ = true;
    end_ = wall + announce_wait_;
    return false;
  }

  // Whether the clock must stand still at wall time `wall`. Once a hold is over this says
  // false until the next one (a wait for GO that ended without GO is counted as a time-out).
  bool holding(double wall) {
    if (end_ < 0) return false;
    if (wall < end_) return true;
    end_ = -1;
    if (awaiting_go_) ++timeouts_;  // still awaiting: ready announcements start no new wait
    return false;
  }

  // The wall time the current hold ends (< 0: no hold pending).
  double until() const { return end_; }
  long timeouts() const { return timeouts_; }  // waits for GO that ended without it

 private:
  static constexpr int16_t kInit = 10, kReady = 1, kGo = 100, kMonitor = -1;
  double go_wait_, announce_wait_;
  std::vector<bool> ready_;
  bool go_seen_ = false, awaiting_go_ = false;
  double end_ = -1;
  long timeouts_ = 0;
};

}  // namespace patrol_stage2d
