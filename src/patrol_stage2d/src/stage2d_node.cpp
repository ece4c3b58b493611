// stage2d_node: one roscpp node that simulates N differential-drive robots on a map_server map
// with Box2D (walls + robot-robot contacts), laser scans (distance-field ray casting plus
// analytic ray-circle hits on other robots), Stage-like odometry, ground truth, tf and /clock.
// This file only starts the node; each concept lives in its own file:
//   config        every ~parameter, validated          world       walls, bodies, contacts, physics step
//   robot_model   drive, odometry, contact counters    laser       scans
//   sim_clock     sim time and /clock                  robot_ros   per-robot topics and tf
//   services      reset, snapshot, set_pose            renderer    window and snapshots
//   simulation_loop  set-up, stepping, pacing, status  world_map   occupancy grid and ray casting
#include <ros/ros.h>

#include "patrol_stage2d/simulation_loop.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "stage2d");
  patrol_stage2d::SimulationLoop sim;
  try {
    sim.setup();
  } catch (const patrol_stage2d::InputError& e) {
    ROS_FATAL("stage2d: %s", e.what());
    ros::shutdown();
    return 2;
  }
  sim.run();
  return 0;
}
