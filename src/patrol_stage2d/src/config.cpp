// Configuration of the simulator: reads and validates every ~parameter (see config.h).
#include "patrol_stage2d/config.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <sys/stat.h>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

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

namespace {

// Numbers of a string or list parameter value; false if the value is neither.
bool numbers_of(XmlRpc::XmlRpcValue& v, const std::string& what, std::vector<double>* out) {
  if (v.getType() == XmlRpc::XmlRpcValue::TypeString) {
    *out = parse_number_list(static_cast<std::string>(v), what);
    return true;
  }
  if (v.getType() != XmlRpc::XmlRpcValue::TypeArray) return false;
  for (int k = 0; k < v.size(); ++k) {
    if (v[k].getType() == XmlRpc::XmlRpcValue::TypeDouble)
      out->push_back(static_cast<double>(v[k]));
    else if (v[k].getType() == XmlRpc::XmlRpcValue::TypeInt)
      out->push_back(static_cast<int>(v[k]));
    else
      throw InputError(what + ": element " + std::to_string(k) + " is not a number");
  }
  return true;
}

// ~graph_vertices "x y x y ..." (m) and ~graph_edges "u v u v ..." (vertex indices).
GraphDrawing read_graph(const std::vector<double>& xy, const std::vector<double>& uv) {
  GraphDrawing g;
  if (xy.size() % 2 != 0)
    throw InputError("parameter ~graph_vertices: " + std::to_string(xy.size()) +
                     " numbers is not a multiple of 2 (x y per vertex)");
  if (uv.size() % 2 != 0)
    throw InputError("parameter ~graph_edges: " + std::to_string(uv.size()) +
                     " numbers is not a multiple of 2 (u v per edge)");
  for (size_t k = 0; k < xy.size(); k += 2) g.pos.emplace_back(xy[k], xy[k + 1]);
  const double n = static_cast<double>(g.pos.size());
  for (size_t k = 0; k < uv.size(); k += 2) {
    for (double id : {uv[k], uv[k + 1]})
      if (id < 0 || id >= n || id != std::floor(id))
        throw InputError("parameter ~graph_edges: " + fmt("%g", id) + " is not a vertex index 0.." +
                         std::to_string(g.pos.size()) + "-1 of ~graph_vertices");
    g.edges.emplace_back(static_cast<int>(uv[k]), static_cast<int>(uv[k + 1]));
  }
  return g;
}

void make_dirs(const std::string& dir) {
  std::string p;
  std::stringstream ss(dir);
  std::string part;
  while (std::getline(ss, part, '/')) {
    if (part.empty()) continue;
    p += (p.empty() && dir[0] != '/' ? "" : "/") + part;
    if (mkdir(p.c_str(), 0755) != 0 && errno != EEXIST)
      throw InputError("parameter ~snapshot_dir: cannot create directory " + p);
  }
  struct stat st;
  if (stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
    throw InputError("parameter ~snapshot_dir: " + dir + " is not a directory");
}

}  // namespace

double ParamReader::positive(const std::string& name, double def, bool allow_zero) const {
  double v = get<double>(name, def);
  if (!(allow_zero ? v >= 0 : v > 0) || !std::isfinite(v))
    throw InputError("parameter ~" + name + " must be " + (allow_zero ? ">= 0" : "> 0") + ", got " + fmt("%g", v));
  return v;
}

bool ParamReader::is_number(const std::string& name) const {
  XmlRpc::XmlRpcValue v;
  if (!pnh_.getParam(name, v)) return false;
  return v.getType() == XmlRpc::XmlRpcValue::TypeDouble || v.getType() == XmlRpc::XmlRpcValue::TypeInt;
}

std::vector<double> ParamReader::numbers(const std::string& name, const char* expected) const {
  std::vector<double> out;
  if (!pnh_.hasParam(name)) return out;
  XmlRpc::XmlRpcValue v;
  pnh_.getParam(name, v);
  if (!numbers_of(v, "parameter ~" + name, &out))
    throw InputError("parameter ~" + name + " must be " + expected);
  return out;
}

std::vector<double> read_poses(const ParamReader& p) {
  if (!p.has("poses")) throw InputError("parameter ~poses is missing (\"x y yaw x y yaw ...\")");
  if (p.is_number("poses"))
    throw InputError("parameter ~poses: needs a multiple of 3 numbers \"x y yaw ...\", got 1");
  std::vector<double> vals = p.numbers("poses", "a string \"x y yaw ...\" or a list of numbers");
  if (vals.empty()) throw InputError("parameter ~poses is empty (need \"x y yaw\" per robot)");
  if (vals.size() % 3 != 0)
    throw InputError("parameter ~poses: " + std::to_string(vals.size()) +
                     " numbers is not a multiple of 3 (x y yaw per robot)");
  return vals;
}

SimConfig read_config(const ParamReader& p) {
  SimConfig c;
  DriveConfig& d = c.drive;
  LaserConfig& l = c.laser;
  d.radius = p.positive("robot_radius", 0.225);
  c.step = p.positive("step", 0.1);  // Stage's default interval_sim (100 ms)
  c.speedup = p.get<double>("speedup", 1.0);
  if (!std::isfinite(c.speedup)) throw InputError("parameter ~speedup must be a number");
  d.cmd_timeout = p.positive("cmd_vel_timeout", 0.5);
  d.max_v = p.positive("max_vel_x", 1.0);
  d.max_w = p.positive("max_vel_theta", 1.0);
  d.acc_v = p.positive("acc_lim_x", 2.5);
  d.acc_w = p.positive("acc_lim_theta", 3.2);
  double fov_deg = p.positive("laser_fov", 270.0);
  if (fov_deg > 360) throw InputError("parameter ~laser_fov must be <= 360 degrees");
  l.fov = fov_deg * M_PI / 180;
  l.samples = p.get<int>("laser_samples", 1081);
  if (l.samples < 1) throw InputError("parameter ~laser_samples must be >= 1");
  l.range_max = p.positive("laser_range_max", 20.0);
  l.range_min = p.positive("laser_range_min", 0.0, true);
  if (l.range_min >= l.range_max) throw InputError("parameter ~laser_range_min must be < ~laser_range_max");
  l.rate = p.positive("laser_rate", 10.0);
  l.x = p.get<double>("laser_x", 0.15);
  l.noise = p.positive("laser_noise", 0.0, true);
  if (p.has("odom_error")) {
    std::vector<double> e = p.numbers("odom_error", "a list [x, y, z, a]");
    if (e.size() != 4)
      throw InputError("parameter ~odom_error needs 4 numbers [x, y, z, a], got " + std::to_string(e.size()));
    for (double x : e)
      if (x < 0 || x >= 1) throw InputError("parameter ~odom_error values must be in [0, 1)");
    c.odom_error = e;
  }
  c.seed = p.get<int>("seed", 0);
  c.gui = p.get<bool>("gui", false);
  c.show_lasers = p.get<bool>("show_lasers", true);
  std::vector<double> graph_xy = p.numbers("graph_vertices", "a string \"x y x y ...\" or a list of numbers");
  std::vector<double> graph_uv = p.numbers("graph_edges", "a string \"u v u v ...\" or a list of numbers");
  c.snapshot_dir = p.get<std::string>("snapshot_dir", "");
  c.snapshot_period = p.positive("snapshot_period", 0.0, true);
  c.status_period = p.positive("status_period", 2.0);
  c.log_period = p.positive("log_period", 5.0);
  c.render_scale = p.positive("render_scale", 0.0, true);
  c.threads = p.get<int>("threads", 0);
  c.scan_always = p.get<bool>("scan_always", false);
  c.sync_timeout = p.positive("sync_timeout", 0.1, true);
  c.reaction_time = p.positive("reaction_time", 0.0, true);
  c.reaction_wait = p.positive("reaction_wait", 0.5, true);
  c.result_wait = p.positive("result_wait", 0.02, true);
  c.go_wait = p.positive("go_wait", 0.5, true);
  c.timer_wait = p.positive("timer_wait", 0.5, true);
  // default: physics sub-steps of at most 10 ms
  c.substeps = p.get<int>("physics_substeps", std::max(1, static_cast<int>(std::ceil(c.step / 0.01 - 1e-9))));
  if (c.substeps < 1) throw InputError("parameter ~physics_substeps must be >= 1");
  if (c.threads < 0) throw InputError("parameter ~threads must be >= 0 (0 = all cores)");
  c.graph = read_graph(graph_xy, graph_uv);
  if (!c.snapshot_dir.empty()) make_dirs(c.snapshot_dir);
  return c;
}

}  // namespace patrol_stage2d
