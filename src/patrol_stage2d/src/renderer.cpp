// Rendering of the map, graph, robots and lasers; window and snapshots (renderer.h).
#include "patrol_stage2d/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <ros/console.h>

#include "patrol_stage2d/util.h"

namespace patrol_stage2d {

namespace {

const cv::Scalar kPalette[] = {
    {255, 0, 0},   {0, 0, 255},   {255, 255, 0}, {255, 0, 255}, {0, 160, 0},   {0, 140, 255},
    {128, 0, 128}, {0, 128, 128}, {128, 128, 0}, {60, 20, 220}, {200, 100, 0}, {80, 80, 80}};

}  // namespace

Renderer::Renderer(const SimConfig& cfg, const WorldMap& map, const std::vector<Robot>& robots, const Laser& laser)
    : map_(map),
      robots_(robots),
      laser_(laser),
      graph_(cfg.graph),
      radius_(cfg.drive.radius),
      gui_(cfg.gui),
      show_lasers_(cfg.show_lasers),
      snapshot_period_(cfg.snapshot_period),
      snapshot_dir_(cfg.snapshot_dir) {
  // base image (also used headless for snapshots)
  double s = cfg.render_scale;
  if (s <= 0) s = std::max(1.0, 1000.0 / std::max(map.width(), map.height()));
  scale_ = s;
  cv::resize(map.render_base(), base_img_, cv::Size(), s, s, cv::INTER_NEAREST);
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
}

cv::Mat Renderer::render(double sim_time) const {
  cv::Mat img = base_img_.clone();
  const double s = scale_, res = map_.resolution();
  const double H = map_.height();
  auto px = [&](double x, double y) {
    return cv::Point(static_cast<int>(std::lround((x - map_.origin_x()) / res * s)),
                     static_cast<int>(std::lround((H - (y - map_.origin_y()) / res) * s)));
  };
  int thick = std::max(1, static_cast<int>(s / 2));
  if (!graph_.empty() && show_graph_) {
    const auto& pos = graph_.pos;
    for (const auto& e : graph_.edges)
      cv::line(img, px(pos[e.first].first, pos[e.first].second), px(pos[e.second].first, pos[e.second].second),
               cv::Scalar(200, 170, 120), thick, cv::LINE_AA);
    for (size_t v = 0; v < pos.size(); ++v) {
      cv::Point c = px(pos[v].first, pos[v].second);
      cv::circle(img, c, std::max(2, static_cast<int>(2 * s)), cv::Scalar(160, 110, 40), cv::FILLED, cv::LINE_AA);
      cv::putText(img, std::to_string(v), c + cv::Point(4, -4), cv::FONT_HERSHEY_SIMPLEX, 0.35, cv::Scalar(120, 70, 0), 1,
                  cv::LINE_AA);
    }
  }
  const LaserConfig& lcfg = laser_.config();
  const double amin = lcfg.angle_min(), inc = lcfg.increment();
  const double laser_x = lcfg.x;
  int every = std::max(1, lcfg.samples / 120);
  for (const Robot& r : robots_) {
    const cv::Scalar col = kPalette[r.id % (sizeof kPalette / sizeof kPalette[0])];
    const b2Vec2& p = r.body->GetPosition();
    double yaw = r.body->GetAngle();
    const LaserCache& scan = laser_.cache(r.id);
    if (show_lasers_ && scan.valid) {
      double lx = p.x + laser_x * std::cos(yaw), ly = p.y + laser_x * std::sin(yaw);
      cv::Scalar lc = col * 0.4 + cv::Scalar(153, 153, 153);
      for (int b = 0; b < lcfg.samples; b += every) {
        double a = yaw + amin + b * inc;
        cv::line(img, px(lx, ly), px(lx + scan.ranges[b] * std::cos(a), ly + scan.ranges[b] * std::sin(a)), lc, 1);
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
  cv::putText(img, "t=" + fmt("%.1f", sim_time) + " s", cv::Point(8, 18), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(0, 0, 200), 1, cv::LINE_AA);
  return img;
}

bool Renderer::write_snapshot(double sim_time, std::string* path) {
  char name[64];
  std::snprintf(name, sizeof name, "snapshot_%06d.png", snapshot_count_);
  *path = (snapshot_dir_.empty() ? std::string("") : snapshot_dir_ + "/") + name;
  cv::Mat img = render(sim_time);
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

void Renderer::update_window(double sim_time) {
  cv::imshow("stage2d", render(sim_time));
  int key = cv::waitKey(1) & 0xff;
  if (key == 'l') show_lasers_ = !show_lasers_;
  if (key == 'g') show_graph_ = !show_graph_;
  if (key == 's') {
    std::string p;
    if (write_snapshot(sim_time, &p)) ROS_INFO("stage2d: wrote %s", p.c_str());
  }
}

}  // namespace patrol_stage2d
