// Drives patrol_stage2d::TimerHold (timer_hold.h) from a script on stdin, for
// tests/unit/test_stage2d_timer_hold.py. First line: wait. Then one event per line:
// "report NAME NEXT" (a report of NAME whose earliest pending deadline is NEXT, < 0: none),
// "hold SIM WALL" (prints 1 if the clock at sim time SIM must stand still at wall time WALL,
// else 0), "counts" (prints "holds timeouts").
#include <iostream>
#include <stdexcept>
#include <string>

#include "hold_check.h"
#include "patrol_stage2d/timer_hold.h"

int main() {
  double wait;
  if (!(std::cin >> wait)) return 2;
  try {
    patrol_stage2d::TimerHold hold(wait);
    return run_events([&hold](const std::string& ev) {
      std::string name;
      double a, b;
      if (ev == "report" && std::cin >> name >> a) {
        hold.on_report(name, a);
      } else if (ev == "hold" && std::cin >> a >> b) {
        std::cout << (hold.holding(a, b) ? 1 : 0) << "\n";
      } else if (ev == "counts") {
        std::cout << hold.holds() << " " << hold.timeouts() << "\n";
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
