// Simulation loop: builds the simulator from its parameters, then runs it -- each step waits
// for the commands of the driven robots, for the robots' reactions (reaction_hold.h), for
// the agents' due timers (timer_hold.h) and around GO (go_hold.h), moves the world,
// publishes the state and the scans that are due, and paces sim time against the wall clock
// (~speedup); it also reports its status (~status topic, periodic log line).
#pragma once

#include <memory>
#include <random>
#include <vector>

#include <ros/ros.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_msgs/Int16MultiArray.h>

#include "patrol_stage2d/config.h"
#include "patrol_stage2d/go_hold.h"
#include "patrol_stage2d/laser.h"
#include "patrol_stage2d/reaction_hold.h"
#include "patrol_stage2d/renderer.h"
#include "patrol_stage2d/robot_ros.h"
#include "patrol_stage2d/services.h"
#include "patrol_stage2d/sim_clock.h"
#include "patrol_stage2d/timer_hold.h"
#include "patrol_stage2d/world.h"

namespace patrol_stage2d {

class SimulationLoop {
 public:
  SimulationLoop() : nh_(), pnh_("~") {}
  void setup();  // throws InputError
  void run();

 private:
  void step_once();
  void publish();
  bool wait_for_commands();  // true if the clock stood still for a reaction
  double stale_command_fraction() const;
  void on_results(const std_msgs::Int16MultiArray::ConstPtr& msg);
  void on_timer_report(const ros::MessageEvent<const std_msgs::Float64MultiArray>& event);
  void publish_status(double rtf);

  ros::NodeHandle nh_, pnh_;
  SimConfig cfg_;
  World world_;
  std::unique_ptr<SimClock> clock_;
  std::unique_ptr<Laser> laser_;
  std::unique_ptr<ReactionHold> hold_;
  std::unique_ptr<RobotsRos> ros_;
  std::unique_ptr<Renderer> renderer_;
  std::unique_ptr<Services> services_;
  ros::Publisher status_pub_;
  std::unique_ptr<GoHold> go_;    // the GO hold (go_hold.h), fed from /results
  ros::Subscriber results_sub_;
  std::unique_ptr<TimerHold> timers_;  // the timer hold (timer_hold.h), fed from /sim_timers
  ros::Subscriber timers_sub_;
  double timer_wall_ = 0;  // wall s the clock stood still for the agents' timers
  long go_holds_ = 0;
  double go_wall_ = 0;     // wall s the clock stood still for GO
  double next_scan_ = 0, next_snapshot_ = 0;
  long sync_waits_ = 0, sync_timeouts_ = 0;
  double held_wall_ = 0;  // wall s the clock stood still for reactions
  double wait_wall_ = 0;  // wall s the clock stood still in all (commands and reactions)
};

}  // namespace patrol_stage2d
