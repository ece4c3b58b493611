// Laser: the scan of every robot's range finder -- distance-field ray casting against the
// walls (cached while the robot stands still: walls never change), analytic ray-circle hits
// on the other robots, optional Gaussian noise -- computed for several robots in parallel.
#pragma once

#include <random>
#include <vector>

#include "patrol_stage2d/config.h"
#include "patrol_stage2d/robot_model.h"
#include "patrol_stage2d/world_map.h"

namespace patrol_stage2d {

// One robot's scan and what can be reused for its next one.
struct LaserCache {
  std::vector<float> ranges;  // the last scan
  bool valid = false;         // `ranges` is a scan of the current state (drawn, published)
  // wall-only ranges of the last scan and the laser pose they were computed at: a robot that
  // has not moved reuses them; robots and noise are applied after
  std::vector<float> wall_ranges;
  double wall_x = NAN, wall_y = NAN, wall_yaw = NAN;
  std::mt19937 rng;  // range noise (seeded per robot: results do not depend on threads)
};

class Laser {
 public:
  // `rngs[i]`: robot i's generator (continues the sequence that drew its odometry errors).
  Laser(const LaserConfig& cfg, double robot_radius, int threads, std::vector<std::mt19937> rngs);

  const LaserConfig& config() const { return cfg_; }
  const LaserCache& cache(int robot) const { return caches_[robot]; }
  void invalidate(int robot) { caches_[robot].valid = false; }
  long scans_computed() const { return scans_computed_; }

  // Computes the scans of the robots `which` (ids) over worker threads.
  void compute(const std::vector<int>& which, const std::vector<Robot>& robots, const WorldMap& map);

 private:
  void scan_robot(const Robot& r, const std::vector<Robot>& robots, const WorldMap& map);

  LaserConfig cfg_;
  double radius_;
  int threads_;
  std::vector<double> beam_cos_, beam_sin_;  // beam directions (laser frame)
  std::vector<LaserCache> caches_;
  long scans_computed_ = 0;
};

}  // namespace patrol_stage2d
