// Drives patrol_stage2d::GoHold (go_hold.h) from a script on stdin, for
// tests/unit/test_stage2d_go_hold.py. First line: team go_wait announce_wait. Then one event
// per line: "msg WALL A B C" (a /results message [A, B, C] at wall time WALL; prints 1 if it
// is the first GO, else 0), "hold WALL" (prints 1 and the hold's end if the clock stands
// still, else 0), "counts" (prints the time-outs).
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "hold_check.h"
#include "patrol_stage2d/go_hold.h"

int main() {
  size_t team;
  double go_wait, announce_wait;
  if (!(std::cin >> team >> go_wait >> announce_wait)) return 2;
  try {
    patrol_stage2d::GoHold hold(team, go_wait, announce_wait);
    return run_events([&hold](const std::string& ev) {
      double wall;
      int a, b, c;
      if (ev == "msg" && std::cin >> wall >> a >> b >> c) {
        std::vector<int16_t> d = {static_cast<int16_t>(a), static_cast<int16_t>(b), static_cast<int16_t>(c)};
        std::cout << (hold.on_results(d, wall) ? 1 : 0) << "\n";
      } else if (ev == "hold" && std::cin >> wall) {
        if (hold.holding(wall)) std::cout << "1 " << hold.until() << "\n";
        else std::cout << "0\n";
      } else if (ev == "counts") {
        std::cout << hold.timeouts() << "\n";
      } else {
        return false;
      }
      return true;
    });
  } catch (const std::invalid_argument& e) {
    std::cerr << e.what() << "\n";
    return 3;
  }
}
