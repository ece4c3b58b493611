// World: walls from the map, robot bodies, contacts and the physics step (world.h).
#include "patrol_stage2d/world.h"

#include <cmath>

#include <ros/console.h>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

void ContactCounter::count(b2Contact* c, int sign) {
  uintptr_t a = c->GetFixtureA()->GetBody()->GetUserData().pointer;
  uintptr_t b = c->GetFixtureB()->GetBody()->GetUserData().pointer;
  for (uintptr_t u : {a, b}) {
    if (!u) continue;
    ContactStats& r = (*robots_)[u - 1].contacts;
    r.touching += sign;
    if (sign > 0) ((a && b) ? r.robot : r.wall)++;
  }
  if (sign > 0) ((a && b) ? robot : wall)++;
}

std::string World::check_pose(double x, double y, double radius, const std::string& what) const {
  std::string at = what + " (" + fmt("%.3f", x) + ", " + fmt("%.3f", y) + ")";
  if (!map_.inside(x, y))
    return at + " is off the map " + map_.yaml_path() + " (x " + fmt("%.3f", map_.origin_x()) + ".." +
           fmt("%.3f", map_.origin_x() + map_.size_x()) + ", y " + fmt("%.3f", map_.origin_y()) + ".." +
           fmt("%.3f", map_.origin_y() + map_.size_y()) + ")";
  double c = map_.clearance(x, y);
  // a small tolerance: start positions computed on cell centres may touch a wall corner
  if (c < radius - 0.5 * map_.resolution())
    return at + " is inside a wall of " + map_.yaml_path() + " (clearance " + fmt("%.3f", c) +
           " m < robot_radius " + fmt("%.3f", radius) + " m)";
  return "";
}

void World::check_start_poses(const std::vector<double>& poses, double radius) const {
  int n = static_cast<int>(poses.size() / 3);
  for (int i = 0; i < n; ++i) {
    std::string why = check_pose(poses[3 * i], poses[3 * i + 1], radius, "parameter ~poses: robot " + std::to_string(i));
    if (!why.empty()) throw InputError(why);
  }
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      double d = std::hypot(poses[3 * i] - poses[3 * j], poses[3 * i + 1] - poses[3 * j + 1]);
      if (d < 2 * radius)
        throw InputError("parameter ~poses: robots " + std::to_string(i) + " and " + std::to_string(j) +
                         " overlap (centres " + fmt("%.3f", d) + " m apart < 2*robot_radius " +
                         fmt("%.3f", 2 * radius) + " m)");
    }
}

void World::build(const std::vector<double>& poses, const SimConfig& cfg, std::vector<std::mt19937>* rngs) {
  // static walls (merged rectangles) + map border
  world_.reset(new b2World(b2Vec2(0, 0)));
  world_->SetAllowSleeping(true);
  b2BodyDef wall_def;
  wall_def.type = b2_staticBody;
  wall_def.position.Set(static_cast<float>(map_.origin_x()), static_cast<float>(map_.origin_y()));
  b2Body* walls = world_->CreateBody(&wall_def);
  const double res = map_.resolution();
  std::vector<CellRect> rects = map_.merged_rects();
  for (const auto& r : rects) {
    b2PolygonShape box;
    float hx = static_cast<float>((r.i1 - r.i0) * res / 2), hy = static_cast<float>((r.j1 - r.j0) * res / 2);
    box.SetAsBox(hx, hy, b2Vec2(static_cast<float>(r.i0 * res) + hx, static_cast<float>(r.j0 * res) + hy), 0);
    b2FixtureDef fd;
    fd.shape = &box;
    fd.friction = 0;
    walls->CreateFixture(&fd);
  }
  {
    float W = static_cast<float>(map_.size_x()), H = static_cast<float>(map_.size_y());
    b2Vec2 c[4] = {{0, 0}, {W, 0}, {W, H}, {0, H}};
    for (int k = 0; k < 4; ++k) {
      b2EdgeShape e;
      e.SetTwoSided(c[k], c[(k + 1) % 4]);
      b2FixtureDef fd;
      fd.shape = &e;
      fd.friction = 0;
      walls->CreateFixture(&fd);
    }
  }
  ROS_INFO("stage2d: map %s: %dx%d cells, %.3f m/cell, %zu merged wall rectangles", map_.yaml_path().c_str(),
           map_.width(), map_.height(), res, rects.size());

  // robots
  int n = static_cast<int>(poses.size() / 3);
  robots_.resize(n);
  rngs->resize(n);
  contacts_.reset(new ContactCounter(&robots_));
  world_->SetContactListener(contacts_.get());
  for (int i = 0; i < n; ++i) {
    Robot& r = robots_[i];
    r.id = i;
    r.ns = "robot_" + std::to_string(i);
    r.start.x = poses[3 * i];
    r.start.y = poses[3 * i + 1];
    r.start.yaw = normalize_angle(poses[3 * i + 2]);
    std::mt19937& rng = (*rngs)[i];
    rng.seed(static_cast<uint32_t>(cfg.seed) * 1000003u + static_cast<uint32_t>(i) * 7919u + 17u);
    init_odometry_errors(&r.odom, cfg.odom_error, &rng);
    b2BodyDef bd;
    bd.type = b2_dynamicBody;
    bd.position.Set(static_cast<float>(r.start.x), static_cast<float>(r.start.y));
    bd.angle = static_cast<float>(r.start.yaw);
    bd.userData.pointer = static_cast<uintptr_t>(i + 1);
    r.body = world_->CreateBody(&bd);
    b2CircleShape circle;
    circle.m_radius = static_cast<float>(cfg.drive.radius);
    b2FixtureDef fd;
    fd.shape = &circle;
    fd.density = 10.0f;
    fd.friction = 0.0f;
    fd.restitution = 0.0f;
    r.body->CreateFixture(&fd);
    r.odom.prev = r.start;
  }
}

void World::step(double dt, int substeps) {
  const float h = static_cast<float>(dt / substeps);
  for (int k = 0; k < substeps; ++k) {
    for (Robot& r : robots_) apply_drive(&r);
    world_->Step(h, 8, 3);
  }
}

}  // namespace patrol_stage2d
