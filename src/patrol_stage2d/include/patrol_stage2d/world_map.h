// Occupancy map of the simulated world: map_server yaml + image loading, a distance field
// for fast ray casting, and merged occupied rectangles for the physics engine.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace patrol_stage2d {

// One-line, user-facing error about a bad input (file, parameter).
struct InputError : public std::runtime_error {
  explicit InputError(const std::string& m) : std::runtime_error(m) {}
};

// Axis-aligned rectangle of occupied cells, in cells: [i0, i1) x [j0, j1) (j counts upward).
struct CellRect {
  int i0, j0, i1, j1;
};

class WorldMap {
 public:
  // Loads a map_server yaml (image, resolution, origin, negate, occupied_thresh, free_thresh).
  // Throws InputError with one line naming the file and the problem.
  void load(const std::string& yaml_path);

  int width() const { return width_; }    // cells along x
  int height() const { return height_; }  // cells along y
  double resolution() const { return res_; }
  double origin_x() const { return ox_; }
  double origin_y() const { return oy_; }
  double size_x() const { return width_ * res_; }
  double size_y() const { return height_ * res_; }
  const std::string& yaml_path() const { return yaml_path_; }
  const std::string& image_path() const { return image_path_; }

  // Cell (i, j), j = 0 is the bottom row (map y grows upward).
  bool occupied(int i, int j) const { return occ_[static_cast<size_t>(j) * width_ + i] != 0; }
  bool inside(double x, double y) const;
  // Distance (m) from the point to the nearest occupied cell or map border (0 inside one).
  double clearance(double x, double y) const;

  // Distance (m) along the ray from (x, y) with heading `a` to the first occupied cell or the
  // map border, or max_range if nothing is hit within max_range.
  double raycast(double x, double y, double a, double max_range) const;
  // Same with a precomputed unit direction.
  double raycast_dir(double x, double y, double dx, double dy, double max_range) const;

  // Occupied cells merged into rectangles (row runs merged vertically).
  std::vector<CellRect> merged_rects() const;

  // Grey image of the map for drawing (row 0 = top, as in the file): occupied black,
  // free white, unknown grey.
  cv::Mat render_base() const;

 private:
  std::string yaml_path_, image_path_;
  int width_ = 0, height_ = 0;
  double res_ = 0.05, ox_ = 0, oy_ = 0;
  std::vector<unsigned char> occ_;    // 1 occupied
  std::vector<unsigned char> state_;  // 0 free, 1 occupied, 2 unknown (for drawing)
  // Distance (cells) from each cell centre to the nearest occupied cell centre or border,
  // on a grid padded by one cell: index (j+1)*(width_+2)+(i+1).
  std::vector<float> dist_;
};

}  // namespace patrol_stage2d
