// KITTI label and calibration files. See kitti_labels.h.
#include "data/kitti_labels.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "util/error.h"

using sl::render::Intrinsics;

namespace sl::data {

using json = nlohmann::json;

namespace {

constexpr const char* kCalibKeys[] = {"P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo"};

double number_field(const std::string& token, const std::string& where, int field) {
  try {
    size_t used = 0;
    const double v = std::stod(token, &used);
    if (used == token.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  fail(where, ": KITTI label field ", field + 1, " is '", token, "', not a finite number");
}

std::string numbers_line(const std::string& key, const std::vector<double>& v) {
  std::string out = key + ":";
  char buf[32];
  for (double x : v) {
    std::snprintf(buf, sizeof buf, " %.12e", x);
    out += buf;
  }
  return out + "\n";
}

// Rows of a JSON matrix, first `rows` rows and `cols` columns, row-major.
std::vector<double> json_matrix(const json& m, int rows, int cols, const std::string& path, const std::string& key) {
  SL_CHECK(m.is_array() && static_cast<int>(m.size()) >= rows, "kitti calibration: '", path, "': '", key,
           "' must have at least ", rows, " rows");
  std::vector<double> out;
  for (int i = 0; i < rows; ++i) {
    SL_CHECK(m[i].is_array() && static_cast<int>(m[i].size()) >= cols, "kitti calibration: '", path, "': '", key,
             "' row ", i, " must have at least ", cols, " numbers");
    for (int j = 0; j < cols; ++j) out.push_back(m[i][j].get<double>());
  }
  return out;
}

std::string calibration_from_json(const std::string& path) {
  std::ifstream f(path);
  json j;
  try {
    j = json::parse(f);
  } catch (const std::exception& e) {
    fail("kitti calibration: '", path, "' is not valid JSON: ", e.what());
  }
  SL_CHECK(j.contains("data_list") && j["data_list"].is_array() && !j["data_list"].empty(), "kitti calibration: '",
           path, "' lacks data_list[0]");
  const json& e = j["data_list"][0];
  SL_CHECK(e.contains("images"), "kitti calibration: '", path, "' lacks data_list[0].images");
  const json& im = e["images"];
  std::string out;
  for (int c = 0; c < 4; ++c) {
    const std::string cam = "CAM" + std::to_string(c);
    SL_CHECK(im.contains(cam) && im[cam].contains("cam2img"), "kitti calibration: '", path, "' lacks images.", cam,
             ".cam2img");
    out += numbers_line("P" + std::to_string(c), json_matrix(im[cam]["cam2img"], 3, 4, path, cam + ".cam2img"));
  }
  SL_CHECK(im.contains("R0_rect"), "kitti calibration: '", path, "' lacks images.R0_rect");
  out += numbers_line("R0_rect", json_matrix(im["R0_rect"], 3, 3, path, "R0_rect"));
  SL_CHECK(e.contains("lidar_points"), "kitti calibration: '", path, "' lacks data_list[0].lidar_points");
  for (const char* key : {"Tr_velo_to_cam", "Tr_imu_to_velo"}) {
    SL_CHECK(e["lidar_points"].contains(key), "kitti calibration: '", path, "' lacks lidar_points.", key);
    out += numbers_line(key, json_matrix(e["lidar_points"][key], 3, 4, path, key));
  }
  return out;
}

}  // namespace

KittiLabel parse_kitti_label(const std::string& line, const std::string& where) {
  std::istringstream is(line);
  std::vector<std::string> t;
  std::string tok;
  while (is >> tok) t.push_back(tok);
  SL_CHECK(t.size() == 15 || t.size() == 16, where, ": a KITTI label has 15 fields (16 with a score), got ", t.size());
  KittiLabel l;
  l.type = t[0];
  l.truncated = number_field(t[1], where, 1);
  const double occ = number_field(t[2], where, 2);
  SL_CHECK(occ == std::floor(occ) && occ >= -1 && occ <= 3, where, ": occlusion '", t[2], "' must be -1, 0, 1, 2 or 3");
  l.occluded = static_cast<int>(occ);
  l.alpha = number_field(t[3], where, 3);
  for (int i = 0; i < 4; ++i) l.box2d[size_t(i)] = number_field(t[size_t(4 + i)], where, 4 + i);
  for (int i = 0; i < 7; ++i) l.box3d[size_t(i)] = number_field(t[size_t(8 + i)], where, 8 + i);
  if (t.size() == 16) {
    l.has_score = true;
    l.score = number_field(t[15], where, 15);
  }
  return l;
}

std::vector<KittiLabel> read_kitti_labels(const std::string& path) {
  std::ifstream f(path);
  SL_CHECK(f.good(), "kitti labels: cannot open '", path, "'");
  std::vector<KittiLabel> out;
  std::string line;
  for (int n = 1; std::getline(f, line); ++n) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    out.push_back(parse_kitti_label(line, path + ":" + std::to_string(n)));
  }
  return out;
}

std::string format_kitti_label(const KittiLabel& l) {
  char buf[512];
  const auto& b = l.box2d;
  const auto& d = l.box3d;
  int n = std::snprintf(buf, sizeof buf, "%s %.2f %d %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f",
                        l.type.c_str(), l.truncated, l.occluded, l.alpha, b[0], b[1], b[2], b[3], d[0], d[1], d[2],
                        d[3], d[4], d[5], d[6]);
  if (l.has_score && n > 0 && n < int(sizeof buf)) std::snprintf(buf + n, sizeof buf - size_t(n), " %.4f", l.score);
  return buf;
}

int occlusion_level(double hidden_fraction) {
  if (!(hidden_fraction >= 0.05)) return 0;
  return hidden_fraction < 0.5 ? 1 : 2;
}

void cover_label(KittiLabel& label, double covered_fraction) {
  if (label.occluded == 3 || label.occluded < 0) return;
  label.occluded = std::max(label.occluded, occlusion_level(covered_fraction));
}

namespace {

// Bird's-eye footprint of a KITTI box (h w l x y z ry, camera frame), grown by `margin` metres.
std::array<glm::dvec2, 4> footprint(const std::array<double, 7>& b, double margin) {
  const double c = std::cos(b[6]), s = std::sin(b[6]), hl = 0.5 * b[2] + margin, hw = 0.5 * b[1] + margin;
  std::array<glm::dvec2, 4> out;
  for (int i = 0; i < 4; ++i) {
    const double dx = (i == 0 || i == 3) ? -hl : hl, dz = i < 2 ? -hw : hw;
    out[size_t(i)] = {b[3] + c * dx + s * dz, b[5] - s * dx + c * dz};
  }
  return out;
}

}  // namespace

bool footprints_within(const std::array<double, 7>& box_a, const std::array<double, 7>& box_b, double margin) {
  const auto a = footprint(box_a, margin), b = footprint(box_b, 0.0);
  for (const auto* poly : {&a, &b})
    for (int i = 0; i < 4; ++i) {
      const glm::dvec2 e = (*poly)[size_t((i + 1) % 4)] - (*poly)[size_t(i)], n(-e.y, e.x);
      double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
      for (const auto& p : a) a0 = std::min(a0, glm::dot(n, p)), a1 = std::max(a1, glm::dot(n, p));
      for (const auto& p : b) b0 = std::min(b0, glm::dot(n, p)), b1 = std::max(b1, glm::dot(n, p));
      if (a1 < b0 || b1 < a0) return false;
    }
  return true;
}

std::string kitti_calibration_text(const std::string& path) {
  std::ifstream f(path);
  SL_CHECK(f.good(), "kitti calibration: cannot open '", path, "'");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '{') return calibration_from_json(path);
  std::map<std::string, std::string> lines;
  std::istringstream is(text);
  std::string line;
  while (std::getline(is, line)) {
    const size_t colon = line.find(':');
    if (colon != std::string::npos) lines[line.substr(0, colon)] = line;
  }
  std::string out;
  for (const char* key : kCalibKeys) {
    SL_CHECK(lines.count(key), "kitti calibration: '", path, "' has no '", key,
             ":' line (a full KITTI calibration has P0-P3, R0_rect, Tr_velo_to_cam and Tr_imu_to_velo)");
    out += lines[key] + "\n";
  }
  return out;
}

std::string kitti_calibration_from_intrinsics(const Intrinsics& k) {
  const std::vector<double> p = {k.fx, 0, k.cx, 0, 0, k.fy, k.cy, 0, 0, 0, 1, 0};
  std::string out;
  for (int c = 0; c < 4; ++c) out += numbers_line("P" + std::to_string(c), p);
  out += numbers_line("R0_rect", {1, 0, 0, 0, 1, 0, 0, 0, 1});
  // No lidar or IMU rig: identity rotations, so a reader that needs the keys finds them.
  out += numbers_line("Tr_velo_to_cam", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});
  out += numbers_line("Tr_imu_to_velo", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0});
  return out;
}

}  // namespace sl::data
