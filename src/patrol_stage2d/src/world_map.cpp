#include "patrol_stage2d/world_map.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace patrol_stage2d {

namespace {

std::string trim(const std::string& s) {
  size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

std::string unquote(const std::string& s) {
  if (s.size() >= 2 && (s[0] == '"' || s[0] == '\'') && s.back() == s[0])
    return s.substr(1, s.size() - 2);
  return s;
}

// Strips a '#' comment that is not inside quotes.
std::string strip_comment(const std::string& s) {
  char q = 0;
  for (size_t k = 0; k < s.size(); ++k) {
    char c = s[k];
    if (q) {
      if (c == q) q = 0;
    } else if (c == '"' || c == '\'') {
      q = c;
    } else if (c == '#' && (k == 0 || s[k - 1] == ' ' || s[k - 1] == '\t')) {
      return s.substr(0, k);
    }
  }
  return s;
}

bool parse_double(const std::string& s, double* v) {
  std::string t = trim(s);
  if (t.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(t.c_str(), &end);
  return end && *end == '\0' && std::isfinite(*v);
}

}  // namespace

void WorldMap::load(const std::string& yaml_path) {
  yaml_path_ = yaml_path;
  std::ifstream in(yaml_path);
  if (yaml_path.empty()) throw InputError("map yaml: no path given (parameter ~map is empty)");
  if (!in) throw InputError(yaml_path + ": cannot open map yaml");
  std::map<std::string, std::string> kv;
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    std::string s = trim(strip_comment(line));
    if (s.empty() || s == "---") continue;
    size_t c = s.find(':');
    if (c == std::string::npos || c == 0)
      throw InputError(yaml_path + ":" + std::to_string(lineno) + ": expected 'key: value', got '" +
                       s + "'");
    kv[trim(s.substr(0, c))] = trim(s.substr(c + 1));
  }
  auto need = [&](const char* k) -> std::string {
    auto it = kv.find(k);
    if (it == kv.end() || it->second.empty())
      throw InputError(yaml_path + ": missing key '" + k + "'");
    return it->second;
  };
  auto number = [&](const char* k, double def, bool required, double lo, double hi) -> double {
    auto it = kv.find(k);
    if (it == kv.end()) {
      if (required) throw InputError(yaml_path + ": missing key '" + k + "'");
      return def;
    }
    double v;
    if (!parse_double(unquote(it->second), &v))
      throw InputError(yaml_path + ": key '" + k + "' is not a number: '" + it->second + "'");
    if (v < lo || v > hi)
      throw InputError(yaml_path + ": key '" + k + "' = " + it->second + " is out of range");
    return v;
  };
  std::string image = unquote(need("image"));
  res_ = number("resolution", 0, true, 1e-9, 1e9);
  std::string origin = need("origin");
  {
    std::string o = origin;
    if (o.size() < 2 || o.front() != '[' || o.back() != ']')
      throw InputError(yaml_path + ": key 'origin' must be a list [x, y, yaw], got '" + origin + "'");
    o = o.substr(1, o.size() - 2);
    std::vector<double> vals;
    std::stringstream ss(o);
    std::string tok;
    while (std::getline(ss, tok, ',')) {
      double v;
      if (!parse_double(tok, &v))
        throw InputError(yaml_path + ": key 'origin' has a non-number '" + trim(tok) + "'");
      vals.push_back(v);
    }
    if (vals.size() != 3)
      throw InputError(yaml_path + ": key 'origin' must have 3 numbers [x, y, yaw], got " +
                       std::to_string(vals.size()));
    ox_ = vals[0];
    oy_ = vals[1];
  }
  double negate = number("negate", 0, false, 0, 1);
  if (negate != 0 && negate != 1) throw InputError(yaml_path + ": key 'negate' must be 0 or 1");
  double occ_th = number("occupied_thresh", 0.65, false, 0, 1);
  double free_th = number("free_thresh", 0.196, false, 0, 1);
  if (free_th > occ_th)
    throw InputError(yaml_path + ": free_thresh is above occupied_thresh");

  if (!image.empty() && image[0] == '/') {
    image_path_ = image;
  } else {
    size_t slash = yaml_path.find_last_of('/');
    image_path_ = (slash == std::string::npos ? std::string("") : yaml_path.substr(0, slash + 1)) + image;
  }
  {
    std::ifstream probe(image_path_);
    if (!probe) throw InputError(image_path_ + ": cannot open map image (from " + yaml_path + ")");
  }
  cv::Mat img;
  try {
    img = cv::imread(image_path_, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    img = cv::Mat();
  }
  if (img.empty()) throw InputError(image_path_ + ": not a readable image (from " + yaml_path + ")");
  if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 257.0);
  if (img.depth() != CV_8U) throw InputError(image_path_ + ": unsupported pixel depth");
  cv::Mat grey;
  if (img.channels() == 1) {
    grey = img;
  } else {
    // map_server: average of the colour channels (alpha ignored)
    std::vector<cv::Mat> ch;
    cv::split(img, ch);
    int n = std::min(3, static_cast<int>(ch.size()));
    cv::Mat acc = cv::Mat::zeros(img.size(), CV_32F);
    for (int k = 0; k < n; ++k) cv::accumulate(ch[k], acc);
    acc.convertTo(grey, CV_8U, 1.0 / n);
  }
  width_ = grey.cols;
  height_ = grey.rows;
  if (width_ < 1 || height_ < 1) throw InputError(image_path_ + ": empty image");
  occ_.assign(static_cast<size_t>(width_) * height_, 0);
  state_.assign(static_cast<size_t>(width_) * height_, 0);
  for (int r = 0; r < height_; ++r) {
    const unsigned char* p = grey.ptr<unsigned char>(r);
    int j = height_ - 1 - r;  // image row 0 is the top of the map
    for (int i = 0; i < width_; ++i) {
      double v = p[i] / 255.0;
      double occ = negate ? v : 1.0 - v;
      size_t k = static_cast<size_t>(j) * width_ + i;
      if (occ > occ_th) {
        occ_[k] = 1;
        state_[k] = 1;
      } else if (occ < free_th) {
        state_[k] = 0;
      } else {
        state_[k] = 2;  // unknown: drawn grey, not an obstacle (like Stage's bitmap)
      }
    }
  }
  // distance field on a padded grid whose border counts as occupied
  int W = width_ + 2, H = height_ + 2;
  cv::Mat freemask(H, W, CV_8U, cv::Scalar(0));
  for (int j = 0; j < height_; ++j)
    for (int i = 0; i < width_; ++i)
      freemask.at<unsigned char>(j + 1, i + 1) = occupied(i, j) ? 0 : 255;
  cv::Mat d;
  cv::distanceTransform(freemask, d, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  dist_.assign(static_cast<size_t>(W) * H, 0.f);
  for (int j = 0; j < H; ++j) std::copy(d.ptr<float>(j), d.ptr<float>(j) + W, dist_.begin() + static_cast<size_t>(j) * W);
}

bool WorldMap::inside(double x, double y) const {
  double gx = (x - ox_) / res_, gy = (y - oy_) / res_;
  return gx >= 0 && gy >= 0 && gx < width_ && gy < height_;
}

double WorldMap::clearance(double x, double y) const {
  if (!inside(x, y)) return 0;
  double gx = (x - ox_) / res_, gy = (y - oy_) / res_;
  int i = static_cast<int>(gx), j = static_cast<int>(gy);
  if (occupied(i, j)) return 0;
  // exact distance to the nearest occupied cell square / border, searched in a window sized
  // by the distance field (cell-centre distances are within one cell of the truth)
  double D = dist_[static_cast<size_t>(j + 1) * (width_ + 2) + (i + 1)];
  int R = static_cast<int>(std::ceil(D + 1.5));
  double best = std::min(std::min(gx, width_ - gx), std::min(gy, height_ - gy));
  for (int jj = std::max(0, j - R); jj <= std::min(height_ - 1, j + R); ++jj)
    for (int ii = std::max(0, i - R); ii <= std::min(width_ - 1, i + R); ++ii) {
      if (!occupied(ii, jj)) continue;
      double dx = std::max({ii - gx, 0.0, gx - (ii + 1)});
      double dy = std::max({jj - gy, 0.0, gy - (jj + 1)});
      best = std::min(best, std::hypot(dx, dy));
    }
  return best * res_;
}

double WorldMap::raycast(double x, double y, double a, double max_range) const {
  return raycast_dir(x, y, std::cos(a), std::sin(a), max_range);
}

double WorldMap::raycast_dir(double x, double y, double dx, double dy, double max_range) const {
  // grid units (cells); the padded distance field is 0 on occupied cells and on the border
  const float px = static_cast<float>((x - ox_) / res_), py = static_cast<float>((y - oy_) / res_);
  const float fdx = static_cast<float>(dx), fdy = static_cast<float>(dy);
  const float tmax = static_cast<float>(max_range / res_);
  const int W = width_ + 2;
  const float* field = dist_.data();
  const float kInf = std::numeric_limits<float>::infinity();
  const float inv_dx = fdx != 0 ? 1.0f / fdx : kInf, inv_dy = fdy != 0 ? 1.0f / fdy : kInf;
  const float fw = static_cast<float>(width_), fh = static_cast<float>(height_);
  float t = 0;
  while (t < tmax) {
    float cx = px + fdx * t, cy = py + fdy * t;
    if (!(cx >= 0 && cy >= 0 && cx < fw && cy < fh)) return t * res_;  // map border
    int i = static_cast<int>(cx), j = static_cast<int>(cy);
    float D = field[(j + 1) * W + (i + 1)];
    if (D == 0.0f) return t * res_;  // occupied cell: t is where the ray entered it
    if (D > 2.0f) {
      // every occupied cell square is at least D - sqrt(2) from any point of this cell:
      // jumping D - 1.5 cannot skip an obstacle
      t += D - 1.5f;
      continue;
    }
    // one DDA step: to the boundary of the current cell
    float tx = fdx > 0 ? (i + 1 - cx) * inv_dx : (fdx < 0 ? (i - cx) * inv_dx : kInf);
    float ty = fdy > 0 ? (j + 1 - cy) * inv_dy : (fdy < 0 ? (j - cy) * inv_dy : kInf);
    t += std::min(tx, ty) + 1e-4f;
  }
  return max_range;
}

std::vector<CellRect> WorldMap::merged_rects() const {
  std::vector<CellRect> out;
  // open rectangles keyed by (i0, i1) of the row run, value = start row
  std::map<std::pair<int, int>, int> open;
  for (int j = 0; j <= height_; ++j) {
    std::map<std::pair<int, int>, int> next;
    if (j < height_) {
      int i = 0;
      while (i < width_) {
        if (!occupied(i, j)) {
          ++i;
          continue;
        }
        int i0 = i;
        while (i < width_ && occupied(i, j)) ++i;
        auto key = std::make_pair(i0, i);
        auto it = open.find(key);
        if (it != open.end()) {
          next[key] = it->second;
          open.erase(it);
        } else {
          next[key] = j;
        }
      }
    }
    for (const auto& kv : open) out.push_back({kv.first.first, kv.second, kv.first.second, j});
    open.swap(next);
  }
  return out;
}

cv::Mat WorldMap::render_base() const {
  cv::Mat img(height_, width_, CV_8UC3);
  for (int r = 0; r < height_; ++r) {
    int j = height_ - 1 - r;
    cv::Vec3b* p = img.ptr<cv::Vec3b>(r);
    for (int i = 0; i < width_; ++i) {
      unsigned char s = state_[static_cast<size_t>(j) * width_ + i];
      unsigned char v = s == 1 ? 0 : (s == 2 ? 160 : 255);
      p[i] = cv::Vec3b(v, v, v);
    }
  }
  return img;
}

}  // namespace patrol_stage2d
