// The event loop shared by the hold drivers (*_check.cpp), which the unit tests compile and
// feed event scripts (tests/unit/stage2d_driver.py).
#pragma once

#include <iostream>
#include <string>

// Reads one event word at a time from stdin and hands it to `handle`, which reads the event's
// arguments from stdin, prints its output and returns false if the event is unknown or its
// arguments are missing. Returns the driver's exit status: 0 at the end of the input, 2 at a
// bad event ("bad event: WORD" on stderr).
template <class Handle>
int run_events(Handle handle) {
  std::string ev;
  while (std::cin >> ev) {
    if (!handle(ev)) {
      std::cerr << "bad event: " << ev << "\n";
      return 2;
    }
  }
  return 0;
}
