// ROS interface of the robots: per robot_i namespace, the cmd_vel subscriber and the odom,
// base_pose_ground_truth and base_scan publishers, and the tf of every robot (odom ->
// base_link -> base_laser_link) on /tf. Messages are published only when someone listens.
// With a reaction hold, it also listens to each robot's move_base goals and results.
#pragma once

#include <vector>

#include <ros/ros.h>

#include "patrol_stage2d/laser.h"
#include "patrol_stage2d/reaction_hold.h"
#include "patrol_stage2d/robot_model.h"
#include "patrol_stage2d/sim_clock.h"

namespace patrol_stage2d {

class RobotsRos {
 public:
  // Subscribes and advertises for every robot; commands are written into robots[i].drive,
  // stamped with clock's sim time. `robots` must outlive this object and never be resized.
  // `hold` (may be null or disabled) hears robot_i/move_base/goal and result and every cmd_vel.
  RobotsRos(ros::NodeHandle& nh, std::vector<Robot>* robots, const SimClock* clock, const LaserConfig& laser,
            ReactionHold* hold);

  bool scan_wanted(int robot) const { return handles_[robot].scan.getNumSubscribers() > 0; }
  // odom, ground truth and tf of every robot at the current sim time.
  void publish_state();
  // The scans just computed for the robots `which`.
  void publish_scans(const std::vector<int>& which, const Laser& laser);

 private:
  struct Handles {
    ros::Subscriber cmd, goal, result;
    ros::Publisher odom, ground_truth, scan;
  };
  std::vector<Robot>* robots_;
  const SimClock* clock_;
  LaserConfig laser_;
  ReactionHold* hold_;
  std::vector<Handles> handles_;
  ros::Publisher tf_pub_;
};

}  // namespace patrol_stage2d
