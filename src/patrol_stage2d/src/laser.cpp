// Laser: ray casting of every robot's scan (laser.h).
#include "patrol_stage2d/laser.h"

#include <algorithm>
#include <cmath>
#include <thread>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

Laser::Laser(const LaserConfig& cfg, double robot_radius, int threads, std::vector<std::mt19937> rngs)
    : cfg_(cfg), radius_(robot_radius), threads_(threads) {
  beam_cos_.resize(cfg_.samples);
  beam_sin_.resize(cfg_.samples);
  double amin = cfg_.angle_min(), inc = cfg_.increment();
  for (int b = 0; b < cfg_.samples; ++b) {
    beam_cos_[b] = std::cos(amin + b * inc);
    beam_sin_[b] = std::sin(amin + b * inc);
  }
  caches_.resize(rngs.size());
  for (size_t i = 0; i < rngs.size(); ++i) {
    caches_[i].rng = rngs[i];
    caches_[i].ranges.assign(cfg_.samples, static_cast<float>(cfg_.range_max));
  }
}

void Laser::scan_robot(const Robot& r, const std::vector<Robot>& robots, const WorldMap& map) {
  LaserCache& lc = caches_[r.id];
  const b2Vec2& p = r.body->GetPosition();
  double yaw = r.body->GetAngle();
  double c = std::cos(yaw), s = std::sin(yaw);
  double lx = p.x + cfg_.x * c, ly = p.y + cfg_.x * s;
  const int nb = cfg_.samples;
  const double range_max = cfg_.range_max;
  if (!(lx == lc.wall_x && ly == lc.wall_y && yaw == lc.wall_yaw) || static_cast<int>(lc.wall_ranges.size()) != nb) {
    lc.wall_ranges.resize(nb);
    for (int b = 0; b < nb; ++b) {
      // beam direction in the map frame
      double dx = beam_cos_[b] * c - beam_sin_[b] * s, dy = beam_cos_[b] * s + beam_sin_[b] * c;
      lc.wall_ranges[b] = static_cast<float>(map.raycast_dir(lx, ly, dx, dy, range_max));
    }
    lc.wall_x = lx;
    lc.wall_y = ly;
    lc.wall_yaw = yaw;
  }
  std::vector<float>& out = lc.ranges;
  out = lc.wall_ranges;
  // other robots: analytic ray-circle intersection over the beams their disc spans
  const double amin = cfg_.angle_min(), inc = nb > 1 ? cfg_.fov / (nb - 1) : 1.0;
  const double r2 = radius_ * radius_;
  for (const Robot& o : robots) {
    if (o.id == r.id) continue;
    const b2Vec2& q = o.body->GetPosition();
    double ex = q.x - lx, ey = q.y - ly;
    double d = std::hypot(ex, ey);
    if (d - radius_ > range_max || d <= radius_) continue;
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
  if (cfg_.noise > 0) {
    std::normal_distribution<double> N(0.0, cfg_.noise);
    for (int b = 0; b < nb; ++b)
      if (out[b] < range_max) out[b] = static_cast<float>(out[b] + N(lc.rng));
  }
  for (int b = 0; b < nb; ++b)
    out[b] = std::min(static_cast<float>(range_max), std::max(static_cast<float>(cfg_.range_min), out[b]));
  lc.valid = true;
}

void Laser::compute(const std::vector<int>& which, const std::vector<Robot>& robots, const WorldMap& map) {
  // robots are split over worker threads (no spinning OpenMP barrier: the machine is shared
  // with the other nodes of an experiment); each robot has its own noise generator, so the
  // result does not depend on the thread count
  const int n = static_cast<int>(which.size());
  int T = threads_ > 0 ? threads_ : static_cast<int>(std::thread::hardware_concurrency());
  T = std::max(1, std::min(T, n));
  auto work = [&](int k0) {
    for (int k = k0; k < n; k += T) scan_robot(robots[which[k]], robots, map);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < T; ++t) pool.emplace_back(work, t);
  work(0);
  for (auto& th : pool) th.join();
  scans_computed_ += n;
}

}  // namespace patrol_stage2d
