// Drives patrol_stage2d::ReactionHold (reaction_hold.h) from a script on stdin, for
// tests/unit/test_stage2d_reaction_hold.py. First line: robots reaction_time goal_wait wait
// result_wait.
// Then one event per line: "goal I ID SIM", "result I ID OK SIM" (OK 1 = SUCCEEDED),
// "cmd I M SIM" (M 1 = a moving command), "hold SIM WALL" (prints 1 if the clock stands still, else 0), "ended I"
// (prints 1 if robot I's goal ended since its last moving command), "counts" (prints
// "holds timeouts").
#include <iostream>
#include <string>

#include "hold_check.h"
#include "patrol_stage2d/reaction_hold.h"

int main() {
  size_t robots;
  double reaction_time, goal_wait, wait, result_wait;
  if (!(std::cin >> robots >> reaction_time >> goal_wait >> wait >> result_wait)) return 2;
  patrol_stage2d::ReactionHold hold(robots, reaction_time, goal_wait, wait, result_wait);
  return run_events([&hold](const std::string& ev) {
    size_t i;
    std::string id;
    double sim, wall;
    int ok;
    if (ev == "goal" && std::cin >> i >> id >> sim) {
      hold.on_goal(i, id, sim);
    } else if (ev == "result" && std::cin >> i >> id >> ok >> sim) {
      hold.on_result(i, id, ok == 1, sim);
    } else if (ev == "cmd" && std::cin >> i >> ok >> sim) {
      hold.on_command(i, ok == 1, sim);
    } else if (ev == "hold" && std::cin >> sim >> wall) {
      std::cout << (hold.holding(sim, wall) ? 1 : 0) << "\n";
    } else if (ev == "ended" && std::cin >> i) {
      std::cout << (hold.goal_ended(i) ? 1 : 0) << "\n";
    } else if (ev == "counts") {
      std::cout << hold.holds() << " " << hold.timeouts() << " " << hold.stop_waits() << " " << hold.stop_timeouts()
                << "\n";
    } else {
      return false;
    }
    return true;
  });
}
