#include "render/camera.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

#include "util/error.h"
#include "util/math.h"

namespace sl::render {

double Intrinsics::horizontal_fov_rad() const { return 2.0 * std::atan(0.5 * width / fx); }
double Intrinsics::vertical_fov_rad() const { return 2.0 * std::atan(0.5 * height / fy); }

Intrinsics Intrinsics::shift_to_pixel_centres() const {
  Intrinsics k = *this;
  k.cx += 0.5;
  k.cy += 0.5;
  return k;
}

Intrinsics Intrinsics::scaled(double sx, double sy) const {
  SL_CHECK(sx > 0.0 && sy > 0.0, "Intrinsics::scaled: scale factors must be > 0, got (", sx,
           ", ", sy, ")");
  Intrinsics k = *this;
  // Continuous coordinates scale about the image corner (0, 0), so cx scales with fx.
  k.fx *= sx;
  k.cx *= sx;
  k.fy *= sy;
  k.cy *= sy;
  k.width = std::max(1, static_cast<int>(std::lround(width * sx)));
  k.height = std::max(1, static_cast<int>(std::lround(height * sy)));
  return k;
}

void validate(const Intrinsics& k, const char* where) {
  SL_CHECK(std::isfinite(k.fx) && std::isfinite(k.fy) && k.fx > 0.0 && k.fy > 0.0, where,
           ": focal lengths must be finite and > 0, got fx=", k.fx, " fy=", k.fy);
  SL_CHECK(std::isfinite(k.cx) && std::isfinite(k.cy), where,
           ": principal point must be finite, got cx=", k.cx, " cy=", k.cy);
  SL_CHECK(k.width > 0 && k.height > 0, where, ": image size must be > 0, got ", k.width, "x",
           k.height);
}

Intrinsics intrinsics_from_fov(double horizontal_fov_rad, int width, int height) {
  SL_CHECK(horizontal_fov_rad > 0.0 && horizontal_fov_rad < kPi,
           "intrinsics_from_fov: horizontal_fov_rad must be in (0, pi), got ", horizontal_fov_rad);
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = k.fy = 0.5 * width / std::tan(0.5 * horizontal_fov_rad);
  k.cx = 0.5 * width;
  k.cy = 0.5 * height;
  validate(k, "intrinsics_from_fov");
  return k;
}

Intrinsics intrinsics_from_matrix3x3(const std::array<double, 9>& m, int width, int height) {
  Intrinsics k;
  k.fx = m[0];
  k.fy = m[4];
  k.cx = m[2];
  k.cy = m[5];
  k.width = width;
  k.height = height;
  validate(k, "intrinsics_from_matrix3x3");
  SL_CHECK(std::fabs(m[1]) <= 1e-6 * k.fx, "intrinsics_from_matrix3x3: skew K[0][1]=", m[1],
           " is not supported");
  SL_CHECK(m[3] == 0.0 && m[6] == 0.0 && m[7] == 0.0 && std::fabs(m[8] - 1.0) < 1e-9,
           "intrinsics_from_matrix3x3: expected the rows [0 fy cy] and [0 0 1], got [", m[3],
           " ", m[4], " ", m[5], "] and [", m[6], " ", m[7], " ", m[8], "]");
  return k;
}

KittiProjection kitti_projection_from_values(const std::array<double, 12>& p, int width,
                                             int height, const char* where) {
  for (double x : p) SL_CHECK(std::isfinite(x), where, ": non-finite value ", x, " in P");
  const std::array<double, 9> k3 = {p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10]};
  KittiProjection out;
  try {
    out.intrinsics = intrinsics_from_matrix3x3(k3, width, height);
  } catch (const Error& e) {
    fail(where, ": the left 3x3 block of P is not a pinhole K: ", e.what());
  }
  // P[:, 3] = K·t with K upper triangular: back-substitute.
  const Intrinsics& k = out.intrinsics;
  const double tz = p[11];
  const double ty = (p[7] - k.cy * tz) / k.fy;
  const double tx = (p[3] - k.cx * tz) / k.fx;
  out.translation = glm::dvec3(tx, ty, tz);
  return out;
}

namespace {

std::vector<double> parse_numbers(const std::string& text, const std::string& path) {
  std::istringstream is(text);
  std::vector<double> values;
  std::string token;
  while (is >> token) {
    char* end = nullptr;
    const double x = std::strtod(token.c_str(), &end);
    SL_CHECK(end != token.c_str() && *end == '\0', "kitti_projection_from_file: '", path,
             "': cannot parse '", token, "' as a number");
    values.push_back(x);
  }
  return values;
}

}  // namespace

KittiProjection kitti_projection_from_file(const std::string& path, int width, int height,
                                           const std::string& key) {
  std::ifstream in(path);
  SL_CHECK(in.good(), "kitti_projection_from_file: cannot open '", path, "'");
  std::string line, keyed_values;
  bool keyed_file = false, found = false;
  std::string bare;
  while (std::getline(in, line)) {
    const size_t colon = line.find(':');
    if (colon != std::string::npos) {
      keyed_file = true;
      std::string name = line.substr(0, colon);
      while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
      size_t b = 0;
      while (b < name.size() && std::isspace(static_cast<unsigned char>(name[b]))) ++b;
      if (name.substr(b) == key) {
        keyed_values = line.substr(colon + 1);
        found = true;
      }
    } else {
      bare += line + " ";
    }
  }
  const std::string where = "kitti_projection_from_file: '" + path + "'";
  std::vector<double> v;
  if (keyed_file) {
    SL_CHECK(found, where, ": no line with key '", key, ":'");
    v = parse_numbers(keyed_values, path);
    SL_CHECK(v.size() == 12, where, ": key '", key, "' has ", v.size(),
             " numbers, expected 12 (3x4)");
  } else {
    v = parse_numbers(bare, path);
    SL_CHECK(v.size() == 12 || v.size() == 16, where, ": expected 12 (3x4) or 16 (4x4) numbers, got ",
             v.size());
    if (v.size() == 16) {
      SL_CHECK(v[12] == 0.0 && v[13] == 0.0 && v[14] == 0.0 && v[15] == 1.0, where,
               ": the last row of a 4x4 matrix must be 0 0 0 1, got ", v[12], " ", v[13], " ",
               v[14], " ", v[15]);
    }
  }
  std::array<double, 12> p{};
  for (int i = 0; i < 12; ++i) p[i] = v[i];
  return kitti_projection_from_values(p, width, height, where.c_str());
}

glm::dmat3 rotation_from_yaw_pitch_roll(double yaw, double pitch, double roll) {
  // R = Ry(−yaw)·Rx(pitch)·Rz(−roll)·F, with F = diag(1, −1, −1) taking the OpenCV axes to a
  // y-up, −z-forward frame. glm matrices are built column by column.
  const double cy = std::cos(yaw), sy = std::sin(yaw);
  const double cp = std::cos(pitch), sp = std::sin(pitch);
  const double cr = std::cos(roll), sr = std::sin(roll);
  const glm::dmat3 ry(glm::dvec3(cy, 0, sy), glm::dvec3(0, 1, 0), glm::dvec3(-sy, 0, cy));
  const glm::dmat3 rx(glm::dvec3(1, 0, 0), glm::dvec3(0, cp, sp), glm::dvec3(0, -sp, cp));
  const glm::dmat3 rz(glm::dvec3(cr, -sr, 0), glm::dvec3(sr, cr, 0), glm::dvec3(0, 0, 1));
  const glm::dmat3 f(glm::dvec3(1, 0, 0), glm::dvec3(0, -1, 0), glm::dvec3(0, 0, -1));
  return ry * rx * rz * f;
}

Camera::Camera(const Intrinsics& intrinsics, const glm::dmat3& rotation,
               const glm::dvec3& position)
    : k_(intrinsics), r_(rotation), t_(position) {
  validate(k_, "Camera");
  const glm::dmat3 should_be_identity = glm::transpose(r_) * r_;
  double err = 0.0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) err = std::fmax(err, std::fabs(should_be_identity[c][r] - (c == r)));
  SL_CHECK(err < 1e-6 && glm::determinant(r_) > 0.0,
           "Camera: rotation must be orthonormal with determinant +1 (max |R^T R - I| = ", err,
           ", det = ", glm::determinant(r_), ")");
  for (int i = 0; i < 3; ++i)
    SL_CHECK(std::isfinite(t_[i]), "Camera: position must be finite, got component ", i, " = ",
             t_[i]);
}

glm::dvec3 Camera::camera_direction(double u, double v) const {
  return glm::dvec3((u - k_.cx) / k_.fx, (v - k_.cy) / k_.fy, 1.0);
}

CameraRay Camera::ray(double u, double v) const {
  return {t_, glm::normalize(r_ * camera_direction(u, v))};
}

glm::dvec3 Camera::unproject(double u, double v, double depth_z) const {
  return camera_to_world(camera_direction(u, v) * depth_z);
}

glm::dvec3 Camera::world_to_camera(const glm::dvec3& p) const {
  return glm::transpose(r_) * (p - t_);
}

glm::dvec3 Camera::camera_to_world(const glm::dvec3& p) const { return r_ * p + t_; }

Projection Camera::project(const glm::dvec3& p_world) const {
  const glm::dvec3 p = world_to_camera(p_world);
  Projection out;
  out.depth = p.z;
  out.in_front = p.z > 1e-12;
  if (!out.in_front) return out;
  out.pixel = glm::dvec2(k_.fx * p.x / p.z + k_.cx, k_.fy * p.y / p.z + k_.cy);
  out.in_image = out.pixel.x >= 0.0 && out.pixel.x < k_.width && out.pixel.y >= 0.0 &&
                 out.pixel.y < k_.height;
  return out;
}

}  // namespace sl::render
