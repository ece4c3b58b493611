// Services of the simulator: reset, snapshot, set_pose (services.h).
#include "patrol_stage2d/services.h"

#include <cmath>
#include <string>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

Services::Services(ros::NodeHandle& nh, ros::NodeHandle& pnh, World* world, double robot_radius, Renderer* renderer,
                   const SimClock* clock)
    : world_(world), radius_(robot_radius), renderer_(renderer), clock_(clock) {
  for (const Robot& r : world->robots()) {
    ros::NodeHandle rn(nh, r.ns);
    int i = r.id;
    set_pose_srvs_.push_back(rn.advertiseService<SetPose::Request, SetPose::Response>(
        "set_pose", [this, i](SetPose::Request& q, SetPose::Response& s) { return on_set_pose(i, q, s); }));
  }
  reset_srv_ = pnh.advertiseService("reset", &Services::on_reset, this);
  snapshot_srv_ = pnh.advertiseService("snapshot", &Services::on_snapshot, this);
}

bool Services::on_reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  for (Robot& r : world_->robots()) place(&r, r.start.x, r.start.y, r.start.yaw);
  ROS_INFO("stage2d: reset: all robots back at their start poses");
  return true;
}

bool Services::on_set_pose(int i, SetPose::Request& q, SetPose::Response& s) {
  std::string why = world_->check_pose(q.pose.x, q.pose.y, radius_, "set_pose robot_" + std::to_string(i));
  if (!std::isfinite(q.pose.theta)) why = "set_pose robot_" + std::to_string(i) + ": theta is not finite";
  if (!why.empty()) {
    s.success = false;
    s.message = why;
    ROS_WARN("stage2d: %s", why.c_str());
    return true;
  }
  place(&world_->robots()[i], q.pose.x, q.pose.y, normalize_angle(q.pose.theta));
  s.success = true;
  s.message = "ok";
  return true;
}

bool Services::on_snapshot(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::string path;
  return renderer_->write_snapshot(clock_->now(), &path);
}

}  // namespace patrol_stage2d
