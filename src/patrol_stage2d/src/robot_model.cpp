// Robot model: drive limits, Stage-like odometry and placement of one robot (robot_model.h).
#include "patrol_stage2d/robot_model.h"

#include <algorithm>
#include <cmath>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

void init_odometry_errors(OdometryModel* odom, const std::vector<double>& odom_error, std::mt19937* rng) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  odom->err_x = U(*rng) * odom_error[0];
  odom->err_y = U(*rng) * odom_error[1];
  odom->err_a = U(*rng) * odom_error[3];
}

void update_drive(Robot* r, const DriveConfig& cfg, double sim_time, double step) {
  DriveState& d = r->drive;
  bool alive = sim_time - d.last_cmd <= cfg.cmd_timeout;
  if (alive && d.moving_command()) {
    ++d.driven_steps;
    if (d.last_cmd < sim_time - 1e-9) ++d.stale_steps;
  }
  double tv = alive ? std::max(-cfg.max_v, std::min(cfg.max_v, d.cmd_v)) : 0.0;
  double tw = alive ? std::max(-cfg.max_w, std::min(cfg.max_w, d.cmd_w)) : 0.0;
  double dv = cfg.acc_v * step, dw = cfg.acc_w * step;
  d.v += std::max(-dv, std::min(dv, tv - d.v));
  d.w += std::max(-dw, std::min(dw, tw - d.w));
}

void apply_drive(Robot* r) {
  const DriveState& d = r->drive;
  if (d.v == 0 && d.w == 0 && !r->body->IsAwake()) return;
  double a = r->body->GetAngle();
  r->body->SetLinearVelocity(b2Vec2(static_cast<float>(d.v * std::cos(a)), static_cast<float>(d.v * std::sin(a))));
  r->body->SetAngularVelocity(static_cast<float>(d.w));
}

void update_odometry(Robot* r, double step) {
  OdometryModel& o = r->odom;
  const b2Vec2& p = r->body->GetPosition();
  double yaw = r->body->GetAngle();
  double dxw = p.x - o.prev.x, dyw = p.y - o.prev.y;
  double c = std::cos(o.prev.yaw), s = std::sin(o.prev.yaw);
  double dx = c * dxw + s * dyw, dy = -s * dxw + c * dyw;
  double da = normalize_angle(yaw - o.prev.yaw);
  o.meas_vx = dx / step;
  o.meas_vy = dy / step;
  o.meas_w = da / step;
  o.oa = normalize_angle(o.oa + da * (1.0 + o.err_a));
  double ex = dx * (1.0 + o.err_x), ey = dy * (1.0 + o.err_y);
  o.ox += ex * std::cos(o.oa) - ey * std::sin(o.oa);
  o.oy += ex * std::sin(o.oa) + ey * std::cos(o.oa);
  o.prev.x = p.x;
  o.prev.y = p.y;
  o.prev.yaw = normalize_angle(yaw);
  if (std::fabs(yaw) > 4 * M_PI) r->body->SetTransform(p, static_cast<float>(normalize_angle(yaw)));
}

void place(Robot* r, double x, double y, double yaw) {
  r->body->SetTransform(b2Vec2(static_cast<float>(x), static_cast<float>(y)), static_cast<float>(yaw));
  r->body->SetLinearVelocity(b2Vec2(0, 0));
  r->body->SetAngularVelocity(0);
  r->body->SetAwake(true);
  DriveState& d = r->drive;
  d.v = d.w = d.cmd_v = d.cmd_w = 0;
  d.last_cmd = -1e9;
  d.prev_cmd = -1e9;
  const b2Vec2& p = r->body->GetPosition();
  r->odom.prev.x = p.x;
  r->odom.prev.y = p.y;
  r->odom.prev.yaw = r->body->GetAngle();
  r->odom.meas_vx = r->odom.meas_vy = r->odom.meas_w = 0;
}

}  // namespace patrol_stage2d
