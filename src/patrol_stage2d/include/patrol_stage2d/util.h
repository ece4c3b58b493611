// Small helpers shared by the simulator's files: angle wrapping and number formatting.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

namespace patrol_stage2d {

// Angle wrapped into [-pi, pi).
inline double normalize_angle(double a) {
  a = std::fmod(a + M_PI, 2 * M_PI);
  if (a < 0) a += 2 * M_PI;
  return a - M_PI;
}

// printf-style formatting of one number, for error and log messages.
inline std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

}  // namespace patrol_stage2d
