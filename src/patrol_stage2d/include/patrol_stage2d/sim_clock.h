// Sim time: counts steps, gives the current sim time and its ROS stamp, publishes /clock.
// Nothing else (pacing against the wall clock is the loop's job).
#pragma once

#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

namespace patrol_stage2d {

class SimClock {
 public:
  explicit SimClock(double step) : step_(step) {}
  void advertise(ros::NodeHandle& nh) { clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10); }

  double step() const { return step_; }
  long steps() const { return steps_; }
  double now() const { return sim_time_; }
  ros::Time stamp() const {
    ros::Time t;
    t.fromSec(sim_time_);
    return t;
  }
  // One step later (sim time = steps * step: no accumulated rounding).
  void advance() { sim_time_ = (++steps_) * step_; }
  void publish() const {
    rosgraph_msgs::Clock ck;
    ck.clock = stamp();
    clock_pub_.publish(ck);
  }

 private:
  double step_;
  long steps_ = 0;
  double sim_time_ = 0;
  ros::Publisher clock_pub_;
};

}  // namespace patrol_stage2d
