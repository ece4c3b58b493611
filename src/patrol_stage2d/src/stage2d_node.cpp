// stage2d_node: one roscpp node that simulates N differential-drive robots on a map_server map
// with Box2D (walls + robot-robot contacts), laser scans (distance-field ray casting plus
// analytic ray-circle hits on other robots), Stage-like odometry, ground truth, tf and /clock.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <thread>
#include <vector>

#include <box2d/box2d.h>
#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/Twist.h>
#include <nav_msgs/Odometry.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/LaserScan.h>
#include <std_msgs/String.h>
#include <std_srvs/Empty.h>
#include <tf2_msgs/TFMessage.h>

#include "patrol_stage2d/SetPose.h"
#include "patrol_stage2d/world_map.h"


using patrol_stage2d::InputError;
using patrol_stage2d::WorldMap;

namespace {

double normalize_angle(double a) {
  a = std::fmod(a + M_PI, 2 * M_PI);
  if (a < 0) a += 2 * M_PI;
  return a - M_PI;
}

geometry_msgs::Quaternion yaw_quat(double yaw) {
  geometry_msgs::Quaternion q;
  q.x = 0;
  q.y = 0;
  q.z = std::sin(yaw / 2);
  q.w = std::cos(yaw / 2);
  return q;
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

// Parses "x y yaw x y yaw ..." (spaces, commas, brackets allowed as separators).
std::vector<double> parse_number_list(const std::string& s, const std::string& what) {
  std::string t = s;
  for (char& c : t)
    if (c == ',' || c == '[' || c == ']' || c == ';' || c == '\n' || c == '\t') c = ' ';
  std::stringstream ss(t);
  std::vector<double> out;
  std::string tok;
  while (ss >> tok) {
    char* end = nullptr;
    double v = std::strtod(tok.c_str(), &end);
    if (!end || *end != '\0' || !std::isfinite(v))
      throw InputError(what + ": '" + tok + "' is not a number");
    out.push_back(v);
  }
  return out;
}

struct GraphDrawing {
  std::vector<cv::Point2d> pos;  // metres
  std::vector<std::pair<int, int>> edges;
};

GraphDrawing load_graph(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open graph file (parameter ~graph_file)");
  std::vector<std::string> tok;
  std::string w;
  while (in >> w) tok.push_back(w);
  size_t k = 0;
  auto num = [&](const char* what) -> double {
    if (k >= tok.size()) throw InputError(path + ": graph file ends early (expected " + what + ")");
    char* end = nullptr;
    double v = std::strtod(tok[k].c_str(), &end);
    if (!end || *end != '\0' || !std::isfinite(v))
      throw InputError(path + ": expected " + what + ", got '" + tok[k] + "'");
    ++k;
    return v;
  };
  double V = num("vertex count");
  if (V < 1 || V != std::floor(V)) throw InputError(path + ": bad vertex count");
  num("width");
  num("height");
  double res = num("resolution");
  double offx = num("offset_x"), offy = num("offset_y");
  if (res <= 0) throw InputError(path + ": resolution must be > 0");
  GraphDrawing g;
  int n = static_cast<int>(V);
  g.pos.resize(n);
  for (int v = 0; v < n; ++v) {
    double id = num("vertex id");
    if (id != v) throw InputError(path + ": vertex ids must be 0..V-1 in order (got " + tok[k - 1] + ")");
    double x = num("x_px"), y = num("y_px");
    g.pos[v] = cv::Point2d(x * res + offx, y * res + offy);
    double deg = num("neighbour count");
    if (deg < 0 || deg != std::floor(deg)) throw InputError(path + ": bad neighbour count at vertex " + std::to_string(v));
    for (int e = 0; e < static_cast<int>(deg); ++e) {
      double nb = num("neighbour id");
      if (k >= tok.size()) throw InputError(path + ": graph file ends early (expected direction)");
      ++k;  // direction
      num("edge cost");
      if (nb < 0 || nb >= V || nb != std::floor(nb))
        throw InputError(path + ": vertex " + std::to_string(v) + " has a bad neighbour id " + tok[k - 3]);
      if (v < static_cast<int>(nb)) g.edges.emplace_back(v, static_cast<int>(nb));
    }
  }
  return g;
}

const cv::Scalar kPalette[] = {
    {255, 0, 0},   {0, 0, 255},   {255, 255, 0}, {255, 0, 255}, {0, 160, 0},   {0, 140, 255},
    {128, 0, 128}, {0, 128, 128}, {128, 128, 0}, {60, 20, 220}, {200, 100, 0}, {80, 80, 80}};

struct Robot {
  int id = 0;
  std::string ns;
  b2Body* body = nullptr;
  double start_x = 0, start_y = 0, start_yaw = 0;
  // command state
  double cmd_v = 0, cmd_w = 0, last_cmd = -1e9;  // last_cmd in sim seconds
  // steps driven by a live command, and those whose newest command arrived before the
  // previous step was published (the controller missed a step: pace too fast for it)
  long driven_steps = 0, stale_steps = 0;
  double v = 0, w = 0;                           // current (acceleration-limited) command
  // measured motion of the last step (robot frame)
  double meas_vx = 0, meas_vy = 0, meas_w = 0;
  double prev_x = 0, prev_y = 0, prev_yaw = 0;
  // odometry estimate (frame robot_i/odom = start pose) and its constant error factors
  double ox = 0, oy = 0, oa = 0;
  double err_x = 0, err_y = 0, err_a = 0;
  // laser
  std::vector<float> ranges;
  bool scan_valid = false;
  // wall-only ranges of the last scan and the laser pose they were computed at: a robot that
  // has not moved reuses them (the walls never change); robots and noise are applied after
  std::vector<float> wall_ranges;
  double wall_x = NAN, wall_y = NAN, wall_yaw = NAN;
  std::mt19937 rng;
  // contacts
  long wall_contacts = 0, robot_contacts = 0;
  int touching = 0;
  ros::Subscriber cmd_sub;
  ros::Publisher odom_pub, gt_pub, scan_pub;
  ros::ServiceServer set_pose_srv;
};

class ContactCounter : public b2ContactListener {
 public:
  explicit ContactCounter(std::vector<Robot>* robots) : robots_(robots) {}
  long wall = 0, robot = 0;
  void BeginContact(b2Contact* c) override { count(c, +1); }
  void EndContact(b2Contact* c) override { count(c, -1); }

 private:
  void count(b2Contact* c, int sign) {
    uintptr_t a = c->GetFixtureA()->GetBody()->GetUserData().pointer;
    uintptr_t b = c->GetFixtureB()->GetBody()->GetUserData().pointer;
    for (uintptr_t u : {a, b}) {
      if (!u) continue;
      Robot& r = (*robots_)[u - 1];
      r.touching += sign;
      if (sign > 0) ((a && b) ? r.robot_contacts : r.wall_contacts)++;
    }
    if (sign > 0) ((a && b) ? robot : wall)++;
  }
  std::vector<Robot>* robots_;
};

class Stage2D {
 public:
  Stage2D() : nh_(), pnh_("~") {}
  void setup();  // throws InputError
  void run();

 private:
  template <typename T>
  T param(const std::string& name, T def) {
    T v;
    if (pnh_.hasParam(name) && !pnh_.getParam(name, v))
      throw InputError("parameter ~" + name + " has the wrong type");
    return pnh_.hasParam(name) ? v : def;
  }
  double positive(const std::string& name, double def, bool allow_zero = false) {
    double v = param<double>(name, def);
    if (!(allow_zero ? v >= 0 : v > 0) || !std::isfinite(v))
      throw InputError("parameter ~" + name + " must be " + (allow_zero ? ">= 0" : "> 0") + ", got " +
                       fmt("%g", v));
    return v;
  }
  std::vector<double> read_poses();
  std::string check_pose(double x, double y, const std::string& what) const;
  void place(Robot& r, double x, double y, double yaw);
  void step_once();
  double stale_command_fraction() const;
  void wait_for_commands();
  void publish_state();
  void compute_scans(const std::vector<int>& which);
  void scan_robot(Robot& r);
  bool wants_scan(const Robot& r) const;
  cv::Mat render();
  bool write_snapshot(std::string* path);
  void publish_status(double rtf);
  bool on_reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool on_snapshot(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  bool on_set_pose(int i, patrol_stage2d::SetPose::Request&, patrol_stage2d::SetPose::Response&);

  ros::NodeHandle nh_, pnh_;
  WorldMap map_;
  std::unique_ptr<b2World> world_;
  std::unique_ptr<ContactCounter> contacts_;
  std::vector<Robot> robots_;
  GraphDrawing graph_;
  bool have_graph_ = false;

  // parameters
  double radius_ = 0.225, step_ = 0.1, speedup_ = 1.0, cmd_timeout_ = 0.5;
  double max_v_ = 1.0, max_w_ = 1.0, acc_v_ = 2.5, acc_w_ = 3.2;
  double laser_fov_ = 270.0 * M_PI / 180, laser_range_max_ = 20, laser_range_min_ = 0;
  double laser_rate_ = 10, laser_x_ = 0.15, laser_noise_ = 0;
  int laser_samples_ = 1081;
  std::vector<double> odom_error_{0.01, 0.01, 0.0, 0.1};
  int seed_ = 0;
  bool gui_ = false, show_lasers_ = true, show_graph_ = true;
  std::string snapshot_dir_;
  double snapshot_period_ = 0, status_period_ = 2.0, log_period_ = 5.0, render_scale_ = 0;
  int threads_ = 0;
  int substeps_ = 5;
  bool scan_always_ = false;  // benchmarking: compute scans without subscribers
  // command-synchronised stepping: before a step, wait (at most sync_timeout_ wall seconds)
  // for a fresh cmd_vel from every robot that was commanded during the previous step
  double sync_timeout_ = 0.1;
  long sync_waits_ = 0, sync_timeouts_ = 0;

  // laser beam directions (robot laser frame)
  std::vector<double> beam_cos_, beam_sin_;

  // time
  long steps_ = 0;
  double sim_time_ = 0, next_scan_ = 0, next_snapshot_ = 0;
  int snapshot_count_ = 0;
  long scans_computed_ = 0;
  cv::Mat base_img_;

  ros::Publisher clock_pub_, tf_pub_, status_pub_;
  ros::ServiceServer reset_srv_, snapshot_srv_;
};

std::vector<double> Stage2D::read_poses() {
  if (!pnh_.hasParam("poses")) throw InputError("parameter ~poses is missing (\"x y yaw x y yaw ...\")");
  XmlRpc::XmlRpcValue v;
  pnh_.getParam("poses", v);
  std::vector<double> vals;
  if (v.getType() == XmlRpc::XmlRpcValue::TypeString) {
    vals = parse_number_list(static_cast<std::string>(v), "parameter ~poses");
  } else if (v.getType() == XmlRpc::XmlRpcValue::TypeArray) {
    for (int k = 0; k < v.size(); ++k) {
      if (v[k].getType() == XmlRpc::XmlRpcValue::TypeDouble)
        vals.push_back(static_cast<double>(v[k]));
      else if (v[k].getType() == XmlRpc::XmlRpcValue::TypeInt)
        vals.push_back(static_cast<int>(v[k]));
      else
        throw InputError("parameter ~poses: element " + std::to_string(k) + " is not a number");
    }
  } else if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble || v.getType() == XmlRpc::XmlRpcValue::TypeInt) {
    throw InputError("parameter ~poses: needs a multiple of 3 numbers \"x y yaw ...\", got 1");
  } else {
    throw InputError("parameter ~poses must be a string \"x y yaw ...\" or a list of numbers");
  }
  if (vals.empty()) throw InputError("parameter ~poses is empty (need \"x y yaw\" per robot)");
  if (vals.size() % 3 != 0)
    throw InputError("parameter ~poses: " + std::to_string(vals.size()) +
                     " numbers is not a multiple of 3 (x y yaw per robot)");
  return vals;
}

// Empty string if a robot can stand at (x, y), else the reason.
std::string Stage2D::check_pose(double x, double y, const std::string& what) const {
  std::string at = what + " (" + fmt("%.3f", x) + ", " + fmt("%.3f", y) + ")";
  if (!map_.inside(x, y))
    return at + " is off the map " + map_.yaml_path() + " (x " + fmt("%.3f", map_.origin_x()) + ".." +
           fmt("%.3f", map_.origin_x() + map_.size_x()) + ", y " + fmt("%.3f", map_.origin_y()) + ".." +
           fmt("%.3f", map_.origin_y() + map_.size_y()) + ")";
  double c = map_.clearance(x, y);
  // a small tolerance: start positions computed on cell centres may touch a wall corner
  if (c < radius_ - 0.5 * map_.resolution())
    return at + " is inside a wall of " + map_.yaml_path() + " (clearance " + fmt("%.3f", c) +
           " m < robot_radius " + fmt("%.3f", radius_) + " m)";
  return "";
}

void Stage2D::setup() {
  std::string map_path = param<std::string>("map", "");
  if (map_path.empty()) throw InputError("parameter ~map (map_server yaml path) is missing or empty");
  map_.load(map_path);

  radius_ = positive("robot_radius", 0.225);
  step_ = positive("step", 0.1);  // Stage's default interval_sim (100 ms)
  speedup_ = param<double>("speedup", 1.0);
  if (!std::isfinite(speedup_)) throw InputError("parameter ~speedup must be a number");
  cmd_timeout_ = positive("cmd_vel_timeout", 0.5);
  max_v_ = positive("max_vel_x", 1.0);
  max_w_ = positive("max_vel_theta", 1.0);
  acc_v_ = positive("acc_lim_x", 2.5);
  acc_w_ = positive("acc_lim_theta", 3.2);
  double fov_deg = positive("laser_fov", 270.0);
  if (fov_deg > 360) throw InputError("parameter ~laser_fov must be <= 360 degrees");
  laser_fov_ = fov_deg * M_PI / 180;
  laser_samples_ = param<int>("laser_samples", 1081);
  if (laser_samples_ < 1) throw InputError("parameter ~laser_samples must be >= 1");
  laser_range_max_ = positive("laser_range_max", 20.0);
  laser_range_min_ = positive("laser_range_min", 0.0, true);
  if (laser_range_min_ >= laser_range_max_) throw InputError("parameter ~laser_range_min must be < ~laser_range_max");
  laser_rate_ = positive("laser_rate", 10.0);
  laser_x_ = param<double>("laser_x", 0.15);
  laser_noise_ = positive("laser_noise", 0.0, true);
  if (pnh_.hasParam("odom_error")) {
    XmlRpc::XmlRpcValue v;
    pnh_.getParam("odom_error", v);
    std::vector<double> e;
    if (v.getType() == XmlRpc::XmlRpcValue::TypeString) {
      e = parse_number_list(static_cast<std::string>(v), "parameter ~odom_error");
    } else if (v.getType() == XmlRpc::XmlRpcValue::TypeArray) {
      for (int k = 0; k < v.size(); ++k) {
        if (v[k].getType() == XmlRpc::XmlRpcValue::TypeDouble) e.push_back(static_cast<double>(v[k]));
        else if (v[k].getType() == XmlRpc::XmlRpcValue::TypeInt) e.push_back(static_cast<int>(v[k]));
        else throw InputError("parameter ~odom_error: element " + std::to_string(k) + " is not a number");
      }
    } else {
      throw InputError("parameter ~odom_error must be a list [x, y, z, a]");
    }
    if (e.size() != 4) throw InputError("parameter ~odom_error needs 4 numbers [x, y, z, a], got " + std::to_string(e.size()));
    for (double x : e)
      if (x < 0 || x >= 1) throw InputError("parameter ~odom_error values must be in [0, 1)");
    odom_error_ = e;
  }
  seed_ = param<int>("seed", 0);
  gui_ = param<bool>("gui", false);
  show_lasers_ = param<bool>("show_lasers", true);
  std::string graph_file = param<std::string>("graph_file", "");
  snapshot_dir_ = param<std::string>("snapshot_dir", "");
  snapshot_period_ = positive("snapshot_period", 0.0, true);
  status_period_ = positive("status_period", 2.0);
  log_period_ = positive("log_period", 5.0);
  render_scale_ = positive("render_scale", 0.0, true);
  threads_ = param<int>("threads", 0);
  scan_always_ = param<bool>("scan_always", false);
  sync_timeout_ = positive("sync_timeout", 0.1, true);
  // default: physics sub-steps of at most 10 ms
  substeps_ = param<int>("physics_substeps", std::max(1, static_cast<int>(std::ceil(step_ / 0.01 - 1e-9))));
  if (substeps_ < 1) throw InputError("parameter ~physics_substeps must be >= 1");
  if (threads_ < 0) throw InputError("parameter ~threads must be >= 0 (0 = all cores)");

  if (!graph_file.empty()) {
    graph_ = load_graph(graph_file);
    have_graph_ = true;
  }
  if (!snapshot_dir_.empty()) {
    std::string cmd_dir;
    std::string p;
    std::stringstream ss(snapshot_dir_);
    std::string part;
    if (snapshot_dir_[0] == '/') p = "";
    while (std::getline(ss, part, '/')) {
      if (part.empty()) continue;
      p += (p.empty() && snapshot_dir_[0] != '/' ? "" : "/") + part;
      if (mkdir(p.c_str(), 0755) != 0 && errno != EEXIST)
        throw InputError("parameter ~snapshot_dir: cannot create directory " + p);
    }
    struct stat st;
    if (stat(snapshot_dir_.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
      throw InputError("parameter ~snapshot_dir: " + snapshot_dir_ + " is not a directory");
  }

  std::vector<double> poses = read_poses();
  int n = static_cast<int>(poses.size() / 3);
  for (int i = 0; i < n; ++i) {
    std::string why = check_pose(poses[3 * i], poses[3 * i + 1], "parameter ~poses: robot " + std::to_string(i));
    if (!why.empty()) throw InputError(why);
  }
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      double d = std::hypot(poses[3 * i] - poses[3 * j], poses[3 * i + 1] - poses[3 * j + 1]);
      if (d < 2 * radius_)
        throw InputError("parameter ~poses: robots " + std::to_string(i) + " and " + std::to_string(j) +
                         " overlap (centres " + fmt("%.3f", d) + " m apart < 2*robot_radius " +
                         fmt("%.3f", 2 * radius_) + " m)");
    }

  // physics world: static walls (merged rectangles) + map border
  world_.reset(new b2World(b2Vec2(0, 0)));
  world_->SetAllowSleeping(true);
  b2BodyDef wall_def;
  wall_def.type = b2_staticBody;
  wall_def.position.Set(static_cast<float>(map_.origin_x()), static_cast<float>(map_.origin_y()));
  b2Body* walls = world_->CreateBody(&wall_def);
  const double res = map_.resolution();
  std::vector<patrol_stage2d::CellRect> rects = map_.merged_rects();
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
  ROS_INFO("stage2d: map %s: %dx%d cells, %.3f m/cell, %zu merged wall rectangles", map_path.c_str(),
           map_.width(), map_.height(), res, rects.size());

  robots_.resize(n);
  contacts_.reset(new ContactCounter(&robots_));
  world_->SetContactListener(contacts_.get());
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int i = 0; i < n; ++i) {
    Robot& r = robots_[i];
    r.id = i;
    r.ns = "robot_" + std::to_string(i);
    r.start_x = poses[3 * i];
    r.start_y = poses[3 * i + 1];
    r.start_yaw = normalize_angle(poses[3 * i + 2]);
    r.rng.seed(static_cast<uint32_t>(seed_) * 1000003u + static_cast<uint32_t>(i) * 7919u + 17u);
    // Stage: constant per-robot integration error, uniform in [-odom_error, +odom_error]
    r.err_x = U(r.rng) * odom_error_[0];
    r.err_y = U(r.rng) * odom_error_[1];
    r.err_a = U(r.rng) * odom_error_[3];
    b2BodyDef bd;
    bd.type = b2_dynamicBody;
    bd.position.Set(static_cast<float>(r.start_x), static_cast<float>(r.start_y));
    bd.angle = static_cast<float>(r.start_yaw);
    bd.userData.pointer = static_cast<uintptr_t>(i + 1);
    r.body = world_->CreateBody(&bd);
    b2CircleShape circle;
    circle.m_radius = static_cast<float>(radius_);
    b2FixtureDef fd;
    fd.shape = &circle;
    fd.density = 10.0f;
    fd.friction = 0.0f;
    fd.restitution = 0.0f;
    r.body->CreateFixture(&fd);
    r.prev_x = r.start_x;
    r.prev_y = r.start_y;
    r.prev_yaw = r.start_yaw;
    r.ranges.assign(laser_samples_, static_cast<float>(laser_range_max_));

    ros::NodeHandle rn(nh_, r.ns);
    r.cmd_sub = rn.subscribe<geometry_msgs::Twist>(
        "cmd_vel", 10,
        [this, i](const geometry_msgs::Twist::ConstPtr& m) {
          Robot& rb = robots_[i];
          rb.cmd_v = std::isfinite(m->linear.x) ? m->linear.x : 0.0;
          rb.cmd_w = std::isfinite(m->angular.z) ? m->angular.z : 0.0;
          rb.last_cmd = sim_time_;
        },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    r.odom_pub = rn.advertise<nav_msgs::Odometry>("odom", 10);
    r.gt_pub = rn.advertise<nav_msgs::Odometry>("base_pose_ground_truth", 10);
    r.scan_pub = rn.advertise<sensor_msgs::LaserScan>("base_scan", 10);
    r.set_pose_srv = rn.advertiseService<patrol_stage2d::SetPose::Request, patrol_stage2d::SetPose::Response>(
        "set_pose", [this, i](patrol_stage2d::SetPose::Request& q, patrol_stage2d::SetPose::Response& s) {
          return on_set_pose(i, q, s);
        });
  }

  beam_cos_.resize(laser_samples_);
  beam_sin_.resize(laser_samples_);
  double amin = -laser_fov_ / 2, inc = laser_samples_ > 1 ? laser_fov_ / (laser_samples_ - 1) : 0;
  for (int b = 0; b < laser_samples_; ++b) {
    beam_cos_[b] = std::cos(amin + b * inc);
    beam_sin_[b] = std::sin(amin + b * inc);
  }

  clock_pub_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", 10);
  tf_pub_ = nh_.advertise<tf2_msgs::TFMessage>("/tf", 100);
  status_pub_ = pnh_.advertise<std_msgs::String>("status", 10, true);
  reset_srv_ = pnh_.advertiseService("reset", &Stage2D::on_reset, this);
  snapshot_srv_ = pnh_.advertiseService("snapshot", &Stage2D::on_snapshot, this);

  // render base image (also used headless for snapshots)
  double s = render_scale_;
  if (s <= 0) s = std::max(1.0, 1000.0 / std::max(map_.width(), map_.height()));
  render_scale_ = s;
  cv::resize(map_.render_base(), base_img_, cv::Size(), s, s, cv::INTER_NEAREST);
  if (gui_) {
    const char* disp = std::getenv("DISPLAY");
    if (!disp || !*disp)
      throw InputError("parameter ~gui is true but DISPLAY is not set (run headless with gui:=false, or under xvfb-run)");
    try {
      cv::namedWindow("stage2d", cv::WINDOW_AUTOSIZE);
    } catch (const cv::Exception& e) {
      throw InputError("parameter ~gui is true but no window can be opened (DISPLAY unset? use xvfb-run): " +
                       std::string(e.what()).substr(0, 120));
    }
  }
  ROS_INFO("stage2d: %d robots, step %.3f s, speedup %g%s, laser %d beams %.1f deg %.1f m @ %.1f Hz", n, step_,
           speedup_, speedup_ <= 0 ? " (as fast as possible)" : "", laser_samples_, fov_deg, laser_range_max_,
           laser_rate_);
}

void Stage2D::place(Robot& r, double x, double y, double yaw) {
  r.body->SetTransform(b2Vec2(static_cast<float>(x), static_cast<float>(y)), static_cast<float>(yaw));
  r.body->SetLinearVelocity(b2Vec2(0, 0));
  r.body->SetAngularVelocity(0);
  r.body->SetAwake(true);
  r.v = r.w = r.cmd_v = r.cmd_w = 0;
  r.last_cmd = -1e9;
  const b2Vec2& p = r.body->GetPosition();
  r.prev_x = p.x;
  r.prev_y = p.y;
  r.prev_yaw = r.body->GetAngle();
  r.meas_vx = r.meas_vy = r.meas_w = 0;
}

bool Stage2D::on_reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  for (Robot& r : robots_) place(r, r.start_x, r.start_y, r.start_yaw);
  ROS_INFO("stage2d: reset: all robots back at their start poses");
  return true;
}

bool Stage2D::on_set_pose(int i, patrol_stage2d::SetPose::Request& q, patrol_stage2d::SetPose::Response& s) {
  std::string why = check_pose(q.pose.x, q.pose.y, "set_pose robot_" + std::to_string(i));
  if (!std::isfinite(q.pose.theta)) why = "set_pose robot_" + std::to_string(i) + ": theta is not finite";
  if (!why.empty()) {
    s.success = false;
    s.message = why;
    ROS_WARN("stage2d: %s", why.c_str());
    return true;
  }
  place(robots_[i], q.pose.x, q.pose.y, normalize_angle(q.pose.theta));
  s.success = true;
  s.message = "ok";
  return true;
}

bool Stage2D::on_snapshot(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::string path;
  return write_snapshot(&path);
}

bool Stage2D::write_snapshot(std::string* path) {
  char name[64];
  std::snprintf(name, sizeof name, "snapshot_%06d.png", snapshot_count_);
  *path = (snapshot_dir_.empty() ? std::string("") : snapshot_dir_ + "/") + name;
  cv::Mat img = render();
  bool ok = false;
  try {
    ok = cv::imwrite(*path, img);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) {
    ROS_ERROR("stage2d: cannot write snapshot %s", path->c_str());
    return false;
  }
  ++snapshot_count_;
  ROS_DEBUG("stage2d: wrote %s", path->c_str());
  return true;
}

bool Stage2D::wants_scan(const Robot& r) const {
  return scan_always_ || r.scan_pub.getNumSubscribers() > 0 || (show_lasers_ && (gui_ || snapshot_period_ > 0));
}

void Stage2D::scan_robot(Robot& r) {
  const b2Vec2& p = r.body->GetPosition();
  double yaw = r.body->GetAngle();
  double c = std::cos(yaw), s = std::sin(yaw);
  double lx = p.x + laser_x_ * c, ly = p.y + laser_x_ * s;
  const int nb = laser_samples_;
  if (!(lx == r.wall_x && ly == r.wall_y && yaw == r.wall_yaw) || static_cast<int>(r.wall_ranges.size()) != nb) {
    r.wall_ranges.resize(nb);
    for (int b = 0; b < nb; ++b) {
      // beam direction in the map frame
      double dx = beam_cos_[b] * c - beam_sin_[b] * s, dy = beam_cos_[b] * s + beam_sin_[b] * c;
      r.wall_ranges[b] = static_cast<float>(map_.raycast_dir(lx, ly, dx, dy, laser_range_max_));
    }
    r.wall_x = lx;
    r.wall_y = ly;
    r.wall_yaw = yaw;
  }
  std::vector<float>& out = r.ranges;
  out = r.wall_ranges;
  // other robots: analytic ray-circle intersection over the beams their disc spans
  const double amin = -laser_fov_ / 2, inc = nb > 1 ? laser_fov_ / (nb - 1) : 1.0;
  const double r2 = radius_ * radius_;
  for (const Robot& o : robots_) {
    if (o.id == r.id) continue;
    const b2Vec2& q = o.body->GetPosition();
    double ex = q.x - lx, ey = q.y - ly;
    double d = std::hypot(ex, ey);
    if (d - radius_ > laser_range_max_ || d <= radius_) continue;
    double half = std::asin(radius_ / d);
    double rel = normalize_angle(std::atan2(ey, ex) - yaw);
    for (double shift : {-2 * M_PI, 0.0, 2 * M_PI}) {
      double lo = rel + shift - half, hi = rel + shift + half;
      int b0 = std::max(0, static_cast<int>(std::ceil((lo - amin) / inc)));
      int b1 = std::min(nb - 1, static_cast<int>(std::floor((hi - amin) / inc)));
      for (int b = b0; b <= b1; ++b) {
        double ux = beam_cos_[b] * c - beam_sin_[b] * s, uy = beam_cos_[b] * s + beam_sin_[b] * c;
        double tc = ex * ux + ey * uy;
        double perp2 = d * d - tc * tc;
        if (perp2 > r2 || tc <= 0) continue;
        double t = tc - std::sqrt(r2 - perp2);
        if (t > 0 && t < out[b]) out[b] = static_cast<float>(t);
      }
    }
  }
  if (laser_noise_ > 0) {
    std::normal_distribution<double> N(0.0, laser_noise_);
    for (int b = 0; b < nb; ++b)
      if (out[b] < laser_range_max_) out[b] = static_cast<float>(out[b] + N(r.rng));
  }
  for (int b = 0; b < nb; ++b)
    out[b] = std::min(static_cast<float>(laser_range_max_), std::max(static_cast<float>(laser_range_min_), out[b]));
  r.scan_valid = true;
}

void Stage2D::compute_scans(const std::vector<int>& which) {
  // robots are split over worker threads (no spinning OpenMP barrier: the machine is shared
  // with the other nodes of an experiment); each robot has its own noise generator, so the
  // result does not depend on the thread count
  const int n = static_cast<int>(which.size());
  int T = threads_ > 0 ? threads_ : static_cast<int>(std::thread::hardware_concurrency());
  T = std::max(1, std::min(T, n));
  auto work = [&](int k0) {
    for (int k = k0; k < n; k += T) scan_robot(robots_[which[k]]);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < T; ++t) pool.emplace_back(work, t);
  work(0);
  for (auto& th : pool) th.join();
  scans_computed_ += n;
}

void Stage2D::step_once() {
  // commands: watchdog, velocity and acceleration limits, differential drive
  for (Robot& r : robots_) {
    bool alive = sim_time_ - r.last_cmd <= cmd_timeout_;
    if (alive && (r.cmd_v != 0 || r.cmd_w != 0)) {
      ++r.driven_steps;
      if (r.last_cmd < sim_time_ - 1e-9) ++r.stale_steps;
    }
    double tv = alive ? std::max(-max_v_, std::min(max_v_, r.cmd_v)) : 0.0;
    double tw = alive ? std::max(-max_w_, std::min(max_w_, r.cmd_w)) : 0.0;
    double dv = acc_v_ * step_, dw = acc_w_ * step_;
    r.v += std::max(-dv, std::min(dv, tv - r.v));
    r.w += std::max(-dw, std::min(dw, tw - r.w));
  }
  // physics sub-steps keep dynamic-dynamic penetration small (Box2D has no CCD between
  // two dynamic bodies); the heading is re-applied before each sub-step
  const float h = static_cast<float>(step_ / substeps_);
  for (int k = 0; k < substeps_; ++k) {
    for (Robot& r : robots_) {
      if (r.v == 0 && r.w == 0 && !r.body->IsAwake()) continue;
      double a = r.body->GetAngle();
      r.body->SetLinearVelocity(b2Vec2(static_cast<float>(r.v * std::cos(a)), static_cast<float>(r.v * std::sin(a))));
      r.body->SetAngularVelocity(static_cast<float>(r.w));
    }
    world_->Step(h, 8, 3);
  }
  sim_time_ = (++steps_) * step_;
  // measured motion and Stage-like odometry (velocity integration with constant error factors)
  for (Robot& r : robots_) {
    const b2Vec2& p = r.body->GetPosition();
    double yaw = r.body->GetAngle();
    double dxw = p.x - r.prev_x, dyw = p.y - r.prev_y;
    double c = std::cos(r.prev_yaw), s = std::sin(r.prev_yaw);
    double dx = c * dxw + s * dyw, dy = -s * dxw + c * dyw;
    double da = normalize_angle(yaw - r.prev_yaw);
    r.meas_vx = dx / step_;
    r.meas_vy = dy / step_;
    r.meas_w = da / step_;
    r.oa = normalize_angle(r.oa + da * (1.0 + r.err_a));
    double ex = dx * (1.0 + r.err_x), ey = dy * (1.0 + r.err_y);
    r.ox += ex * std::cos(r.oa) - ey * std::sin(r.oa);
    r.oy += ex * std::sin(r.oa) + ey * std::cos(r.oa);
    r.prev_x = p.x;
    r.prev_y = p.y;
    r.prev_yaw = normalize_angle(yaw);
    if (std::fabs(yaw) > 4 * M_PI) r.body->SetTransform(p, static_cast<float>(normalize_angle(yaw)));
  }
}

void Stage2D::publish_state() {
  ros::Time stamp;
  stamp.fromSec(sim_time_);
  rosgraph_msgs::Clock ck;
  ck.clock = stamp;
  clock_pub_.publish(ck);

  bool want_tf = tf_pub_.getNumSubscribers() > 0;
  tf2_msgs::TFMessage tfm;
  if (want_tf) tfm.transforms.reserve(2 * robots_.size());
  for (Robot& r : robots_) {
    const std::string base = r.ns + "/base_link";
    if (r.odom_pub.getNumSubscribers() > 0) {
      nav_msgs::Odometry o;
      o.header.stamp = stamp;
      o.header.frame_id = r.ns + "/odom";
      o.child_frame_id = base;
      o.pose.pose.position.x = r.ox;
      o.pose.pose.position.y = r.oy;
      o.pose.pose.orientation = yaw_quat(r.oa);
      o.twist.twist.linear.x = r.meas_vx * (1.0 + r.err_x);
      o.twist.twist.linear.y = r.meas_vy * (1.0 + r.err_y);
      o.twist.twist.angular.z = r.meas_w * (1.0 + r.err_a);
      r.odom_pub.publish(o);
    }
    if (r.gt_pub.getNumSubscribers() > 0) {
      nav_msgs::Odometry g;
      g.header.stamp = stamp;
      g.header.frame_id = "map";
      g.child_frame_id = base;
      const b2Vec2& p = r.body->GetPosition();
      g.pose.pose.position.x = p.x;
      g.pose.pose.position.y = p.y;
      g.pose.pose.orientation = yaw_quat(r.body->GetAngle());
      g.twist.twist.linear.x = r.meas_vx;
      g.twist.twist.linear.y = r.meas_vy;
      g.twist.twist.angular.z = r.meas_w;
      r.gt_pub.publish(g);
    }
    if (want_tf) {
      geometry_msgs::TransformStamped t;
      t.header.stamp = stamp;
      t.header.frame_id = r.ns + "/odom";
      t.child_frame_id = base;
      t.transform.translation.x = r.ox;
      t.transform.translation.y = r.oy;
      t.transform.rotation = yaw_quat(r.oa);
      tfm.transforms.push_back(t);
      geometry_msgs::TransformStamped l;
      l.header.stamp = stamp;
      l.header.frame_id = base;
      l.child_frame_id = r.ns + "/base_laser_link";
      l.transform.translation.x = laser_x_;
      l.transform.rotation.w = 1.0;
      tfm.transforms.push_back(l);
    }
  }
  if (want_tf) tf_pub_.publish(tfm);

  if (sim_time_ + 1e-9 >= next_scan_) {
    next_scan_ += 1.0 / laser_rate_;
    if (next_scan_ < sim_time_) next_scan_ = sim_time_ + 1.0 / laser_rate_;
    std::vector<int> which;
    for (Robot& r : robots_)
      if (wants_scan(r)) which.push_back(r.id);
      else r.scan_valid = false;
    if (!which.empty()) compute_scans(which);
    const double amin = -laser_fov_ / 2, inc = laser_samples_ > 1 ? laser_fov_ / (laser_samples_ - 1) : 0;
    for (int i : which) {
      Robot& r = robots_[i];
      if (r.scan_pub.getNumSubscribers() == 0) continue;
      sensor_msgs::LaserScan m;
      m.header.stamp = stamp;
      m.header.frame_id = r.ns + "/base_laser_link";
      m.angle_min = static_cast<float>(amin);
      m.angle_max = static_cast<float>(amin + inc * (laser_samples_ - 1));
      m.angle_increment = static_cast<float>(inc);
      m.time_increment = 0;
      m.scan_time = static_cast<float>(1.0 / laser_rate_);
      m.range_min = static_cast<float>(laser_range_min_);
      m.range_max = static_cast<float>(laser_range_max_);
      m.ranges = r.ranges;
      r.scan_pub.publish(m);
    }
  }
}

cv::Mat Stage2D::render() {
  cv::Mat img = base_img_.clone();
  const double s = render_scale_, res = map_.resolution();
  const double H = map_.height();
  auto px = [&](double x, double y) {
    return cv::Point(static_cast<int>(std::lround((x - map_.origin_x()) / res * s)),
                     static_cast<int>(std::lround((H - (y - map_.origin_y()) / res) * s)));
  };
  int thick = std::max(1, static_cast<int>(s / 2));
  if (have_graph_ && show_graph_) {
    for (const auto& e : graph_.edges)
      cv::line(img, px(graph_.pos[e.first].x, graph_.pos[e.first].y), px(graph_.pos[e.second].x, graph_.pos[e.second].y),
               cv::Scalar(200, 170, 120), thick, cv::LINE_AA);
    for (size_t v = 0; v < graph_.pos.size(); ++v) {
      cv::Point c = px(graph_.pos[v].x, graph_.pos[v].y);
      cv::circle(img, c, std::max(2, static_cast<int>(2 * s)), cv::Scalar(160, 110, 40), cv::FILLED, cv::LINE_AA);
      cv::putText(img, std::to_string(v), c + cv::Point(4, -4), cv::FONT_HERSHEY_SIMPLEX, 0.35, cv::Scalar(120, 70, 0), 1,
                  cv::LINE_AA);
    }
  }
  const double amin = -laser_fov_ / 2, inc = laser_samples_ > 1 ? laser_fov_ / (laser_samples_ - 1) : 0;
  int every = std::max(1, laser_samples_ / 120);
  for (const Robot& r : robots_) {
    const cv::Scalar col = kPalette[r.id % (sizeof kPalette / sizeof kPalette[0])];
    const b2Vec2& p = r.body->GetPosition();
    double yaw = r.body->GetAngle();
    if (show_lasers_ && r.scan_valid) {
      double lx = p.x + laser_x_ * std::cos(yaw), ly = p.y + laser_x_ * std::sin(yaw);
      cv::Scalar lc = col * 0.4 + cv::Scalar(153, 153, 153);
      for (int b = 0; b < laser_samples_; b += every) {
        double a = yaw + amin + b * inc;
        cv::line(img, px(lx, ly), px(lx + r.ranges[b] * std::cos(a), ly + r.ranges[b] * std::sin(a)), lc, 1);
      }
    }
  }
  for (const Robot& r : robots_) {
    const cv::Scalar col = kPalette[r.id % (sizeof kPalette / sizeof kPalette[0])];
    const b2Vec2& p = r.body->GetPosition();
    double yaw = r.body->GetAngle();
    int rad = std::max(3, static_cast<int>(std::lround(radius_ / res * s)));
    cv::Point c = px(p.x, p.y);
    cv::circle(img, c, rad, col, cv::FILLED, cv::LINE_AA);
    cv::line(img, c, px(p.x + radius_ * std::cos(yaw), p.y + radius_ * std::sin(yaw)), cv::Scalar(0, 0, 0),
             std::max(1, rad / 4), cv::LINE_AA);
    cv::putText(img, std::to_string(r.id), c + cv::Point(rad, -rad), cv::FONT_HERSHEY_SIMPLEX, 0.5, col, 1, cv::LINE_AA);
  }
  cv::putText(img, "t=" + fmt("%.1f", sim_time_) + " s", cv::Point(8, 18), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(0, 0, 200), 1, cv::LINE_AA);
  return img;
}

void Stage2D::wait_for_commands() {
  // A robot is waited for if its newest command arrived during the previous step (it is
  // being driven at the step rate) but none has arrived since the last state was published.
  // A controller that stops, or commands more slowly than the step, is not waited for after
  // one missed step, so a dead node costs at most one timeout. A robot told to stand still
  // is not waited for either: a controller that stopped it (goal reached, planning a new
  // path) often sends nothing more for a while, and a late start costs one step at most.
  if (sync_timeout_ <= 0) return;
  auto pending = [this]() {
    for (const Robot& r : robots_)
      if (r.last_cmd >= sim_time_ - step_ - 1e-9 && r.last_cmd < sim_time_ - 1e-9 &&
          (r.cmd_v != 0.0 || r.cmd_w != 0.0))
        return true;
    return false;
  };
  if (!pending()) return;
  ++sync_waits_;
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                         std::chrono::duration<double>(sync_timeout_));
  while (ros::ok() && pending()) {
    if (std::chrono::steady_clock::now() >= deadline) {
      ++sync_timeouts_;
      return;
    }
    ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.001));
  }
}

double Stage2D::stale_command_fraction() const {
  long driven = 0, stale = 0;
  for (const Robot& r : robots_) {
    driven += r.driven_steps;
    stale += r.stale_steps;
  }
  return driven ? static_cast<double>(stale) / driven : 0.0;
}

void Stage2D::publish_status(double rtf) {
  std::ostringstream js;
  long wall = 0, rob = 0;
  double wall_now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  js << "{\"sim_time\": " << fmt("%.3f", sim_time_) << ", \"wall_time\": " << fmt("%.3f", wall_now) << ", \"steps\": " << steps_ << ", \"rtf\": " << fmt("%.3f", rtf)
     << ", \"speedup\": " << speedup_ << ", \"robots\": " << robots_.size() << ", \"scans_computed\": " << scans_computed_
     << ", \"contacts\": [";
  for (size_t i = 0; i < robots_.size(); ++i) {
    const Robot& r = robots_[i];
    wall += r.wall_contacts;
    rob += r.robot_contacts;
    js << (i ? ", " : "") << "{\"wall\": " << r.wall_contacts << ", \"robot\": " << r.robot_contacts
       << ", \"touching\": " << (r.touching > 0 ? "true" : "false") << "}";
  }
  js << "], \"wall_contacts\": " << contacts_->wall << ", \"robot_contacts\": " << contacts_->robot
     << ", \"stale_command_fraction\": " << fmt("%.4f", stale_command_fraction())
     << ", \"sync_waits\": " << sync_waits_ << ", \"sync_timeouts\": " << sync_timeouts_ << "}";
  std_msgs::String m;
  m.data = js.str();
  status_pub_.publish(m);
}

void Stage2D::run() {
  using Clock = std::chrono::steady_clock;
  auto wall0 = Clock::now();
  auto pace_wall = wall0;
  double pace_sim = 0;
  auto status_wall = wall0, log_wall = wall0, gui_wall = wall0;
  double status_sim = 0, log_sim = 0;
  double rtf = 0;
  publish_status(0);
  while (ros::ok()) {
    ros::spinOnce();
    wait_for_commands();
    step_once();
    publish_state();
    if (snapshot_period_ > 0 && sim_time_ + 1e-9 >= next_snapshot_) {
      std::string p;
      write_snapshot(&p);
      next_snapshot_ += snapshot_period_;
      if (next_snapshot_ < sim_time_) next_snapshot_ = sim_time_ + snapshot_period_;
    }
    auto now = Clock::now();
    if (gui_ && std::chrono::duration<double>(now - gui_wall).count() >= 1.0 / 20) {
      gui_wall = now;
      cv::imshow("stage2d", render());
      int key = cv::waitKey(1) & 0xff;
      if (key == 'l') show_lasers_ = !show_lasers_;
      if (key == 'g') show_graph_ = !show_graph_;
      if (key == 's') {
        std::string p;
        if (write_snapshot(&p)) ROS_INFO("stage2d: wrote %s", p.c_str());
      }
    }
    double since_status = std::chrono::duration<double>(now - status_wall).count();
    if (since_status >= status_period_) {
      rtf = (sim_time_ - status_sim) / since_status;
      status_sim = sim_time_;
      status_wall = now;
      publish_status(rtf);
    }
    double since_log = std::chrono::duration<double>(now - log_wall).count();
    if (since_log >= log_period_) {
      ROS_INFO("stage2d: sim time %.1f s, real-time factor %.2f (speedup %g), %zu robots, contacts wall %ld robot %ld, "
               "stale commands %.1f%%, command waits %ld (timeouts %ld)",
               sim_time_, (sim_time_ - log_sim) / since_log, speedup_, robots_.size(), contacts_->wall, contacts_->robot,
               100.0 * stale_command_fraction(), sync_waits_, sync_timeouts_);
      log_sim = sim_time_;
      log_wall = now;
    }
    if (speedup_ > 0) {
      auto target = pace_wall + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>((sim_time_ - pace_sim) / speedup_));
      now = Clock::now();
      if (target > now) {
        std::this_thread::sleep_until(target);
      } else if (std::chrono::duration<double>(now - target).count() > 0.5) {
        // too far behind: do not try to catch up in a burst
        pace_wall = now;
        pace_sim = sim_time_;
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "stage2d");
  Stage2D sim;
  try {
    sim.setup();
  } catch (const InputError& e) {
    ROS_FATAL("stage2d: %s", e.what());
    ros::shutdown();
    return 2;
  }
  sim.run();
  return 0;
}
