// Services of the simulator: ~reset (every robot back at its start pose), ~snapshot (write a
// PNG now) and robot_i/set_pose (move one robot, refused off the map or inside a wall).
#pragma once

#include <vector>

#include <ros/ros.h>
#include <std_srvs/Empty.h>

#include "patrol_stage2d/SetPose.h"
#include "patrol_stage2d/renderer.h"
#include "patrol_stage2d/sim_clock.h"
#include "patrol_stage2d/world.h"

namespace patrol_stage2d {

class Services {
 public:
  Services(ros::NodeHandle& nh, ros::NodeHandle& pnh, World* world, double robot_radius, Renderer* renderer,
           const SimClock* clock);

 private:
  bool on_reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool on_snapshot(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool on_set_pose(int i, SetPose::Request& q, SetPose::Response& s);

  World* world_;
  double radius_;
  Renderer* renderer_;
  const SimClock* clock_;
  ros::ServiceServer reset_srv_, snapshot_srv_;
  std::vector<ros::ServiceServer> set_pose_srvs_;
};

}  // namespace patrol_stage2d
