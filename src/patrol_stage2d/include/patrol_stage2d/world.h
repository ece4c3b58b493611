// World: the static environment built from the occupancy map (Box2D walls and map border),
// the robots' bodies in it, the contact bookkeeping, and the physics step. Knows nothing of
// ROS, sensors or drawing.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <box2d/box2d.h>

#include "patrol_stage2d/config.h"
#include "patrol_stage2d/robot_model.h"
#include "patrol_stage2d/world_map.h"

namespace patrol_stage2d {

// Counts the beginning of robot-wall and robot-robot contacts (per robot and in total).
class ContactCounter : public b2ContactListener {
 public:
  explicit ContactCounter(std::vector<Robot>* robots) : robots_(robots) {}
  long wall = 0, robot = 0;
  void BeginContact(b2Contact* c) override { count(c, +1); }
  void EndContact(b2Contact* c) override { count(c, -1); }

 private:
  void count(b2Contact* c, int sign);
  std::vector<Robot>* robots_;
};

class World {
 public:
  // Loads the map (throws InputError naming the yaml and the problem).
  void load_map(const std::string& yaml_path) { map_.load(yaml_path); }
  const WorldMap& map() const { return map_; }

  // Empty string if a robot of radius `radius` can stand at (x, y), else the reason.
  std::string check_pose(double x, double y, double radius, const std::string& what) const;
  // Checks every start pose (on the map, off the walls, not overlapping); throws InputError.
  void check_start_poses(const std::vector<double>& poses, double radius) const;

  // Builds the physics world: merged wall rectangles and the map border, then one disc body
  // per start pose (robot i has user data i + 1); odometry errors drawn from each robot's
  // generator, seeded from `seed` and the robot id.
  void build(const std::vector<double>& poses, const SimConfig& cfg, std::vector<std::mt19937>* rngs);

  std::vector<Robot>& robots() { return robots_; }
  const std::vector<Robot>& robots() const { return robots_; }
  const ContactCounter& contacts() const { return *contacts_; }

  // One step of `dt` sim seconds in `substeps` physics sub-steps; the drive is re-applied
  // before each (Box2D has no CCD between two dynamic bodies: sub-steps keep
  // dynamic-dynamic penetration small).
  void step(double dt, int substeps);

 private:
  WorldMap map_;
  std::unique_ptr<b2World> world_;
  std::unique_ptr<ContactCounter> contacts_;
  std::vector<Robot> robots_;
};

}  // namespace patrol_stage2d
