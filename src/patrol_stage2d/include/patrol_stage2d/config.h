// Configuration of the simulator: every ~parameter of the node, read and validated in one
// place; a bad value raises InputError with one line naming the parameter.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <ros/ros.h>

#include "patrol_stage2d/world_map.h"

namespace patrol_stage2d {

// Differential drive of every robot (body size, limits, command watchdog).
struct DriveConfig {
  double radius = 0.225;      // m
  double max_v = 1.0, max_w = 1.0;
  double acc_v = 2.5, acc_w = 3.2;
  double cmd_timeout = 0.5;   // sim seconds without cmd_vel before the robot stops
};

// Laser of every robot (Hokuyo-like defaults).
struct LaserConfig {
  double fov = 270.0 * M_PI / 180;  // rad
  int samples = 1081;
  double range_max = 20, range_min = 0;
  double rate = 10;   // scans per sim second
  double x = 0.15;    // laser offset ahead of the robot centre (m)
  double noise = 0;   // std dev of the range noise (m)
  // angle of the first beam and between beams
  double angle_min() const { return -fov / 2; }
  double increment() const { return samples > 1 ? fov / (samples - 1) : 0; }
};

// Patrol graph to draw (metres): given by the launch as the Python core computed it.
struct GraphDrawing {
  std::vector<std::pair<double, double>> pos;
  std::vector<std::pair<int, int>> edges;
  bool empty() const { return pos.empty(); }
};

struct SimConfig {
  double step = 0.1;           // sim seconds per step (Stage's interval_sim)
  double speedup = 1.0;        // <= 0: as fast as possible
  int substeps = 1;            // physics sub-steps per step
  int threads = 0;             // scan threads, 0 = all cores
  double sync_timeout = 0.1;   // wall seconds to wait for a driven robot's next command
  double reaction_time = 0.0;  // sim seconds a robot's reaction may take before the clock waits for it
  double reaction_wait = 0.5;  // wall seconds the clock waits at most per reaction (0 = never)
  double result_wait = 0.02;   // wall seconds the clock waits for a result after a driven robot's stop
  double go_wait = 0.5;        // wall seconds the clock stands still once GO is seen on /results (0 = never)
  double timer_wait = 0.5;     // wall seconds the clock waits at most for an agent process's due timers (0 = never)
  int seed = 0;
  std::vector<double> odom_error{0.01, 0.01, 0.0, 0.1};
  bool scan_always = false;    // benchmarking: compute scans without subscribers
  DriveConfig drive;
  LaserConfig laser;
  // drawing, snapshots, status
  bool gui = false, show_lasers = true;
  GraphDrawing graph;
  std::string snapshot_dir;
  double snapshot_period = 0, status_period = 2.0, log_period = 5.0, render_scale = 0;
};

// Typed access to the node's private parameters.
class ParamReader {
 public:
  explicit ParamReader(const ros::NodeHandle& pnh) : pnh_(pnh) {}
  template <typename T>
  T get(const std::string& name, T def) const {
    T v;
    if (pnh_.hasParam(name) && !pnh_.getParam(name, v))
      throw InputError("parameter ~" + name + " has the wrong type");
    return pnh_.hasParam(name) ? v : def;
  }
  // A number > 0 (>= 0 with allow_zero).
  double positive(const std::string& name, double def, bool allow_zero = false) const;
  // A list of numbers given as a string "a b c" (commas, brackets allowed) or a yaml list;
  // empty if the parameter is not set.
  std::vector<double> numbers(const std::string& name, const char* expected) const;
  bool has(const std::string& name) const { return pnh_.hasParam(name); }
  // True if the parameter is set to a single number.
  bool is_number(const std::string& name) const;

 private:
  ros::NodeHandle pnh_;
};

// Parses "x y yaw x y yaw ..." (spaces, commas, brackets allowed as separators).
std::vector<double> parse_number_list(const std::string& s, const std::string& what);

// Every parameter but ~map and ~poses; creates ~snapshot_dir if needed.
SimConfig read_config(const ParamReader& p);
// ~poses: x y yaw per robot (a multiple of 3 numbers).
std::vector<double> read_poses(const ParamReader& p);

}  // namespace patrol_stage2d
