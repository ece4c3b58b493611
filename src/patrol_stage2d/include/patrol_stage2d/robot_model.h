// Robot model: what one simulated robot is (a Box2D disc), how it drives (watchdog, velocity
// and acceleration limits, differential drive), its Stage-like odometry with constant error
// factors, and its contact counters. No ROS and no sensors here.
#pragma once

#include <random>
#include <string>

#include <box2d/box2d.h>

#include "patrol_stage2d/config.h"

namespace patrol_stage2d {

struct Pose2D {
  double x = 0, y = 0, yaw = 0;
};

// Velocity command as received and the acceleration-limited velocity being driven.
struct DriveState {
  double cmd_v = 0, cmd_w = 0, last_cmd = -1e9;  // last_cmd in sim seconds
  double prev_cmd = -1e9;                        // sim time of the step of the command before (another step)
  double v = 0, w = 0;                           // current (acceleration-limited) command
  // steps driven by a live command, and those whose newest command arrived before the
  // previous step was published (the controller missed a step: pace too fast for it)
  long driven_steps = 0, stale_steps = 0;
  bool moving_command() const { return cmd_v != 0.0 || cmd_w != 0.0; }
};

// Motion measured over the last step and the odometry estimate (frame robot_i/odom = start
// pose) drifting by its constant per-robot error factors, as Stage's odometry does.
struct OdometryModel {
  double meas_vx = 0, meas_vy = 0, meas_w = 0;  // robot frame, last step
  Pose2D prev;                                   // true pose at the previous step
  double ox = 0, oy = 0, oa = 0;                 // odometry estimate
  double err_x = 0, err_y = 0, err_a = 0;        // constant error factors
};

// Contacts of one robot with walls and other robots (counted at their beginning).
struct ContactStats {
  long wall = 0, robot = 0;
  int touching = 0;  // contacts going on now
};

struct Robot {
  int id = 0;
  std::string ns;  // robot_<id>
  Pose2D start;
  b2Body* body = nullptr;
  DriveState drive;
  OdometryModel odom;
  ContactStats contacts;
};

// Draws the robot's constant odometry error factors, uniform in [-odom_error, +odom_error]
// (x, y, -, a), from `rng`.
void init_odometry_errors(OdometryModel* odom, const std::vector<double>& odom_error, std::mt19937* rng);

// Applies the watchdog and the velocity and acceleration limits to the newest command.
void update_drive(Robot* r, const DriveConfig& cfg, double sim_time, double step);

// Sets the body's velocity from the driven command (heading re-read from the body).
void apply_drive(Robot* r);

// After a step: measured motion and the odometry estimate.
void update_odometry(Robot* r, double step);

// Puts the robot at (x, y, yaw) standing still, forgetting its command.
void place(Robot* r, double x, double y, double yaw);

}  // namespace patrol_stage2d
