// Rendering: every drawing of the world in one place -- the map, the patrol graph, the
// robots and their laser beams -- for the optional OpenCV window and the PNG snapshots.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "patrol_stage2d/config.h"
#include "patrol_stage2d/laser.h"
#include "patrol_stage2d/robot_model.h"
#include "patrol_stage2d/world_map.h"

namespace patrol_stage2d {

class Renderer {
 public:
  // Prepares the scaled map image; with cfg.gui opens the window (throws InputError if no
  // display can be used).
  Renderer(const SimConfig& cfg, const WorldMap& map, const std::vector<Robot>& robots, const Laser& laser);

  // The lasers are drawn (so their scans are needed) in the window or periodic snapshots.
  bool draws_lasers() const { return show_lasers_ && (gui_ || snapshot_period_ > 0); }
  // Writes snapshot_%06d.png into ~snapshot_dir (the working directory if empty).
  bool write_snapshot(double sim_time, std::string* path);
  // Redraws the window and handles its keys (l lasers, g graph, s snapshot).
  void update_window(double sim_time);

 private:
  cv::Mat render(double sim_time) const;

  const WorldMap& map_;
  const std::vector<Robot>& robots_;
  const Laser& laser_;
  GraphDrawing graph_;
  double radius_, scale_;
  bool gui_, show_lasers_, show_graph_ = true;
  double snapshot_period_;
  std::string snapshot_dir_;
  int snapshot_count_ = 0;
  cv::Mat base_img_;
};

}  // namespace patrol_stage2d
