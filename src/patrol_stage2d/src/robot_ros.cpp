// ROS interface of the robots: cmd_vel in; odom, ground truth, tf and scans out (robot_ros.h).
#include "patrol_stage2d/robot_ros.h"

#include <cmath>

#include <actionlib_msgs/GoalStatus.h>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/Twist.h>
#include <move_base_msgs/MoveBaseActionGoal.h>
#include <move_base_msgs/MoveBaseActionResult.h>
#include <nav_msgs/Odometry.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

namespace patrol_stage2d {

namespace {

geometry_msgs::Quaternion yaw_quat(double yaw) {
  geometry_msgs::Quaternion q;
  q.x = 0;
  q.y = 0;
  q.z = std::sin(yaw / 2);
  q.w = std::cos(yaw / 2);
  return q;
}

}  // namespace

RobotsRos::RobotsRos(ros::NodeHandle& nh, std::vector<Robot>* robots, const SimClock* clock, const LaserConfig& laser,
                     ReactionHold* hold)
    : robots_(robots), clock_(clock), laser_(laser), hold_(hold && hold->enabled() ? hold : nullptr),
      handles_(robots->size()) {
  for (size_t i = 0; i < robots->size(); ++i) {
    ros::NodeHandle rn(nh, (*robots)[i].ns);
    Handles& h = handles_[i];
    h.cmd = rn.subscribe<geometry_msgs::Twist>(
        "cmd_vel", 10,
        [this, i](const geometry_msgs::Twist::ConstPtr& m) {
          DriveState& d = (*robots_)[i].drive;
          d.cmd_v = std::isfinite(m->linear.x) ? m->linear.x : 0.0;
          d.cmd_w = std::isfinite(m->angular.z) ? m->angular.z : 0.0;
          if (clock_->now() > d.last_cmd + 1e-9) d.prev_cmd = d.last_cmd;
          d.last_cmd = clock_->now();
          if (hold_) hold_->on_command(i, d.moving_command(), clock_->now());
        },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    if (hold_) {
      h.goal = rn.subscribe<move_base_msgs::MoveBaseActionGoal>(
          "move_base/goal", 10,
          [this, i](const move_base_msgs::MoveBaseActionGoal::ConstPtr& m) {
            hold_->on_goal(i, m->goal_id.id, clock_->now());
          },
          ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
      h.result = rn.subscribe<move_base_msgs::MoveBaseActionResult>(
          "move_base/result", 10,
          [this, i](const move_base_msgs::MoveBaseActionResult::ConstPtr& m) {
            hold_->on_result(i, m->status.goal_id.id, m->status.status == actionlib_msgs::GoalStatus::SUCCEEDED,
                             clock_->now());
          },
          ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    }
    h.odom = rn.advertise<nav_msgs::Odometry>("odom", 10);
    h.ground_truth = rn.advertise<nav_msgs::Odometry>("base_pose_ground_truth", 10);
    h.scan = rn.advertise<sensor_msgs::LaserScan>("base_scan", 10);
  }
  tf_pub_ = nh.advertise<tf2_msgs::TFMessage>("/tf", 100);
}

void RobotsRos::publish_state() {
  const ros::Time stamp = clock_->stamp();
  bool want_tf = tf_pub_.getNumSubscribers() > 0;
  tf2_msgs::TFMessage tfm;
  if (want_tf) tfm.transforms.reserve(2 * robots_->size());
  for (const Robot& r : *robots_) {
    const Handles& h = handles_[r.id];
    const OdometryModel& od = r.odom;
    const std::string base = r.ns + "/base_link";
    if (h.odom.getNumSubscribers() > 0) {
      nav_msgs::Odometry o;
      o.header.stamp = stamp;
      o.header.frame_id = r.ns + "/odom";
      o.child_frame_id = base;
      o.pose.pose.position.x = od.ox;
      o.pose.pose.position.y = od.oy;
      o.pose.pose.orientation = yaw_quat(od.oa);
      o.twist.twist.linear.x = od.meas_vx * (1.0 + od.err_x);
      o.twist.twist.linear.y = od.meas_vy * (1.0 + od.err_y);
      o.twist.twist.angular.z = od.meas_w * (1.0 + od.err_a);
      h.odom.publish(o);
    }
    if (h.ground_truth.getNumSubscribers() > 0) {
      nav_msgs::Odometry g;
      g.header.stamp = stamp;
      g.header.frame_id = "map";
      g.child_frame_id = base;
      const b2Vec2& p = r.body->GetPosition();
      g.pose.pose.position.x = p.x;
      g.pose.pose.position.y = p.y;
      g.pose.pose.orientation = yaw_quat(r.body->GetAngle());
      g.twist.twist.linear.x = od.meas_vx;
      g.twist.twist.linear.y = od.meas_vy;
      g.twist.twist.angular.z = od.meas_w;
      h.ground_truth.publish(g);
    }
    if (want_tf) {
      geometry_msgs::TransformStamped t;
      t.header.stamp = stamp;
      t.header.frame_id = r.ns + "/odom";
      t.child_frame_id = base;
      t.transform.translation.x = od.ox;
      t.transform.translation.y = od.oy;
      t.transform.rotation = yaw_quat(od.oa);
      tfm.transforms.push_back(t);
      geometry_msgs::TransformStamped l;
      l.header.stamp = stamp;
      l.header.frame_id = base;
      l.child_frame_id = r.ns + "/base_laser_link";
      l.transform.translation.x = laser_.x;
      l.transform.rotation.w = 1.0;
      tfm.transforms.push_back(l);
    }
  }
  if (want_tf) tf_pub_.publish(tfm);
}

void RobotsRos::publish_scans(const std::vector<int>& which, const Laser& laser) {
  const ros::Time stamp = clock_->stamp();
  const double amin = laser_.angle_min(), inc = laser_.increment();
  for (int i : which) {
    const Handles& h = handles_[i];
    if (h.scan.getNumSubscribers() == 0) continue;
    sensor_msgs::LaserScan m;
    m.header.stamp = stamp;
    m.header.frame_id = (*robots_)[i].ns + "/base_laser_link";
    m.angle_min = static_cast<float>(amin);
    m.angle_max = static_cast<float>(amin + inc * (laser_.samples - 1));
    m.angle_increment = static_cast<float>(inc);
    m.time_increment = 0;
    m.scan_time = static_cast<float>(1.0 / laser_.rate);
    m.range_min = static_cast<float>(laser_.range_min);
    m.range_max = static_cast<float>(laser_.range_max);
    m.ranges = laser.cache(i).ranges;
    h.scan.publish(m);
  }
}

}  // namespace patrol_stage2d
