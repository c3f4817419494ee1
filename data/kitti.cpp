#include "data/kitti.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "util/error.h"
#include "util/random.h"

using sl::render::Camera;
using sl::render::Intrinsics;
using sl::render::kitti_projection_from_file;
using sl::render::kitti_projection_from_values;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::data {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

glm::dmat4 mat4_row_major(const json& m, const std::string& path, const char* key) {
  SL_CHECK(m.is_array() && m.size() >= 3, "read_kitti_calibration: '", path, "': '", key, "' must be a 3×4 or 4×4 matrix");
  glm::dmat4 out(1.0);
  for (int i = 0; i < static_cast<int>(m.size()) && i < 4; ++i) {
    SL_CHECK(m[i].is_array() && m[i].size() == 4, "read_kitti_calibration: '", path, "': '", key, "' row ", i,
             " must hold 4 numbers");
    for (int j = 0; j < 4; ++j) {
      SL_CHECK(m[i][j].is_number() && std::isfinite(m[i][j].get<double>()), "read_kitti_calibration: '", path,
               "': '", key, "' row ", i, " must hold 4 finite numbers, got ",
               m[i][j].is_number() ? m[i][j].dump() : std::string(m[i][j].type_name()));
      out[j][i] = m[i][j].get<double>();
    }
  }
  return out;
}

KittiCalibration from_json(const std::string& path, int width, int height) {
  std::ifstream f(path);
  SL_CHECK(f.good(), "read_kitti_calibration: cannot open '", path, "'");
  json j;
  try {
    j = json::parse(f);
  } catch (const std::exception& e) {
    fail("read_kitti_calibration: '", path, "' is not valid JSON: ", e.what());
  }
  const json* cam = nullptr;
  if (j.contains("data_list") && j["data_list"].is_array() && !j["data_list"].empty()) {
    const json& e = j["data_list"][0];
    if (e.contains("images") && e["images"].contains("CAM2")) cam = &e["images"]["CAM2"];
  }
  SL_CHECK(cam && cam->contains("cam2img"), "read_kitti_calibration: '", path,
           "' lacks data_list[0].images.CAM2.cam2img");
  KittiCalibration c;
  const glm::dmat4 p = mat4_row_major((*cam)["cam2img"], path, "cam2img");
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 4; ++k) c.p2_row_major[static_cast<size_t>(4 * i + k)] = p[k][i];
  c.p2 = kitti_projection_from_values(c.p2_row_major, width, height, path.c_str());
  if (cam->contains("lidar2cam")) {
    c.lidar_to_cam = mat4_row_major((*cam)["lidar2cam"], path, "lidar2cam");
    c.has_lidar = true;
  }
  return c;
}

// KITTI object-benchmark text: "KEY: numbers" lines. P2 goes through render/camera.h.
KittiCalibration from_text(const std::string& path, int width, int height) {
  KittiCalibration c;
  c.p2 = kitti_projection_from_file(path, width, height, "P2");
  std::ifstream f(path);
  std::string line;
  std::vector<double> p2, r0, tr;
  bool bare = true;
  std::vector<double> all;
  while (std::getline(f, line)) {
    const size_t colon = line.find(':');
    std::istringstream in(colon == std::string::npos ? line : line.substr(colon + 1));
    std::vector<double> v;
    for (double x; in >> x;) v.push_back(x);
    if (colon == std::string::npos) {
      all.insert(all.end(), v.begin(), v.end());
      continue;
    }
    bare = false;
    const std::string key = line.substr(0, colon);
    if (key == "P2") p2 = v;
    if (key == "R0_rect") r0 = v;
    if (key == "Tr_velo_to_cam") tr = v;
  }
  if (bare) p2 = all;
  SL_CHECK(p2.size() >= 12, "read_kitti_calibration: '", path, "': P2 needs 12 numbers, got ", p2.size());
  for (size_t i = 0; i < 12; ++i) c.p2_row_major[i] = p2[i];
  if (tr.size() == 12) {
    glm::dmat4 t(1.0), r(1.0);
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 4; ++k) t[k][i] = tr[static_cast<size_t>(4 * i + k)];
    if (r0.size() == 9)
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) r[k][i] = r0[static_cast<size_t>(3 * i + k)];
    c.lidar_to_cam = r * t;
    c.has_lidar = true;
  }
  return c;
}

}  // namespace

KittiCalibration read_kitti_calibration(const std::string& path, int width, int height) {
  SL_CHECK(fs::is_regular_file(path), "read_kitti_calibration: no such file '", path, "'");
  return fs::path(path).extension() == ".json" ? from_json(path, width, height) : from_text(path, width, height);
}

std::vector<glm::vec4> read_velodyne(const std::string& path) {
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  SL_CHECK(f.good(), "read_velodyne: cannot open '", path, "'");
  const std::streamsize bytes = f.tellg();
  SL_CHECK(bytes >= 0 && bytes % 16 == 0, "read_velodyne: '", path, "' has ", bytes,
           " bytes, not a multiple of 16 (x y z intensity as float32)");
  std::vector<glm::vec4> pts(static_cast<size_t>(bytes / 16));
  f.seekg(0);
  f.read(reinterpret_cast<char*>(pts.data()), bytes);
  SL_CHECK(f.good() || bytes == 0, "read_velodyne: failed reading '", path, "'");
  return pts;
}

namespace {

// Lidar point → (u, v, z) in camera 2 via P2 · lidar_to_cam.
glm::dvec3 project_point(const glm::vec4& p, const KittiCalibration& c, glm::dvec3* camera_point) {
  const glm::dvec4 x = c.lidar_to_cam * glm::dvec4(p.x, p.y, p.z, 1.0);
  const auto& P = c.p2_row_major;
  const double a = P[0] * x.x + P[1] * x.y + P[2] * x.z + P[3];
  const double b = P[4] * x.x + P[5] * x.y + P[6] * x.z + P[7];
  const double z = P[8] * x.x + P[9] * x.y + P[10] * x.z + P[11];
  if (camera_point) *camera_point = glm::dvec3(x) + c.p2.translation;
  return {a / z, b / z, z};
}

constexpr double kMinDepth = 0.5;

}  // namespace

Tensor lidar_depth(const std::vector<glm::vec4>& points, const KittiCalibration& c) {
  SL_CHECK(c.has_lidar, "lidar_depth: the calibration has no lidar-to-camera transform");
  const int W = c.p2.intrinsics.width, H = c.p2.intrinsics.height;
  Tensor depth = Tensor::zeros({H, W});
  float* d = depth.data<float>();
  for (const glm::vec4& p : points) {
    if (!std::isfinite(p.x + p.y + p.z)) continue;
    const glm::dvec3 uvz = project_point(p, c, nullptr);
    if (!(uvz.z > kMinDepth)) continue;
    const long col = std::lround(uvz.x), row = std::lround(uvz.y);
    if (col < 0 || row < 0 || col >= W || row >= H) continue;
    float& slot = d[static_cast<size_t>(row) * W + col];
    if (slot == 0.0f || uvz.z < slot) slot = static_cast<float>(uvz.z);
  }
  return depth;
}

GroundPlane fit_ground_plane(const std::vector<glm::dvec3>& pts, uint64_t seed) {
  GroundPlane g;
  std::vector<glm::dvec3> low;
  for (const glm::dvec3& p : pts)
    if (p.y > 0.5 && p.z > kMinDepth && p.z < 40.0) low.push_back(p);  // below the camera, near range
  if (low.size() < 20) return g;
  Rng rng(seed, 0x6A0D);
  const double tol = 0.12;
  glm::dvec3 best_abc(0.0);
  int best = 0;
  for (int it = 0; it < 300; ++it) {
    const glm::dvec3& p0 = low[static_cast<size_t>(rng.randint(static_cast<int64_t>(low.size())))];
    const glm::dvec3& p1 = low[static_cast<size_t>(rng.randint(static_cast<int64_t>(low.size())))];
    const glm::dvec3& p2 = low[static_cast<size_t>(rng.randint(static_cast<int64_t>(low.size())))];
    glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
    if (glm::length(n) < 1e-9) continue;
    n = glm::normalize(n);
    if (std::abs(n.y) < 0.9) continue;  // a road, not a wall
    // n·X = n·p0  ⇔  y = a x + b z + c
    const glm::dvec3 abc(-n.x / n.y, -n.z / n.y, glm::dot(n, p0) / n.y);
    int count = 0;
    for (const glm::dvec3& p : low) count += std::abs(abc.x * p.x + abc.y * p.z + abc.z - p.y) < tol;
    if (count > best) best = count, best_abc = abc;
  }
  if (best < 20) return g;
  // Least-squares refinement on the inliers (normal equations of y = a x + b z + c).
  glm::dmat3 ata(0.0);
  glm::dvec3 aty(0.0);
  int n_in = 0;
  for (const glm::dvec3& p : low) {
    if (std::abs(best_abc.x * p.x + best_abc.y * p.z + best_abc.z - p.y) >= tol) continue;
    const glm::dvec3 r(p.x, p.z, 1.0);
    ata += glm::outerProduct(r, r);
    aty += r * p.y;
    ++n_in;
  }
  const glm::dvec3 abc = std::abs(glm::determinant(ata)) > 1e-12 ? glm::inverse(ata) * aty : best_abc;
  g = {true, abc.x, abc.y, abc.z, n_in};
  return g;
}

Tensor densify_depth(const Tensor& sparse, const Intrinsics& k, const std::vector<glm::dvec3>& camera_points,
                     const DensifyParams& prm, GroundPlane* plane_out) {
  SL_CHECK(sparse.defined() && sparse.dim() == 2 && sparse.dtype() == DType::F32 && sparse.size(0) == k.height &&
               sparse.size(1) == k.width,
           "densify_depth: expected F32 [", k.height, ", ", k.width, "] depth, got ",
           sparse.defined() ? sparse.describe() : "undefined");
  SL_CHECK(prm.radius_px >= 0 && prm.radius_px <= 64, "densify_depth: radius_px must be in [0, 64], got ", prm.radius_px);
  const int H = k.height, W = k.width, r = prm.radius_px;
  const Tensor src = sparse.contiguous();
  const float* s = src.data<float>();
  Tensor out = Tensor::zeros({H, W});
  float* d = out.data<float>();
  auto valid = [](float v) { return v > 0.0f && std::isfinite(v); };
#pragma omp parallel for schedule(dynamic, 4)
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float v0 = s[static_cast<size_t>(y) * W + x];
      if (valid(v0)) {
        d[static_cast<size_t>(y) * W + x] = v0;
        continue;
      }
      int best_d2 = r * r + 1;
      float best = 0.0f;
      for (int dy = -r; dy <= r; ++dy) {
        const int yy = y + dy;
        if (yy < 0 || yy >= H) continue;
        for (int dx = -r; dx <= r; ++dx) {
          const int xx = x + dx, d2 = dx * dx + dy * dy;
          if (xx < 0 || xx >= W || d2 > best_d2) continue;
          const float v = s[static_cast<size_t>(yy) * W + xx];
          if (!valid(v)) continue;
          if (d2 < best_d2 || v < best) best_d2 = d2, best = v;
        }
      }
      d[static_cast<size_t>(y) * W + x] = best;
    }
  GroundPlane g;
  if (prm.ground_plane && !camera_points.empty()) g = fit_ground_plane(camera_points);
  if (g.found) {
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        float& v = d[static_cast<size_t>(y) * W + x];
        if (v > 0.0f) continue;
        // Ray (dx, dy, 1)·t meets y = a x + b z + c at t = c / (dy − a·dx − b); t is the depth z.
        const double dx = (x - k.cx) / k.fx, dy = (y - k.cy) / k.fy;
        const double den = dy - g.a * dx - g.b;
        if (!(den > 1e-9)) continue;
        const double t = g.c / den;
        if (t > kMinDepth && t <= prm.max_ground_distance_m) v = static_cast<float>(t);
      }
  }
  if (plane_out) *plane_out = g;
  return out;
}

KittiLidar load_kitti_lidar(const std::string& calibration_path, const std::string& velodyne_path, int width,
                            int height) {
  KittiLidar l;
  l.calibration = read_kitti_calibration(calibration_path, width, height);
  const render::Intrinsics& k = l.calibration.p2.intrinsics;
  SL_CHECK(k.cx > 0 && k.cx < width && k.cy > 0 && k.cy < height, "load_kitti_lidar: '", calibration_path,
           "': principal point (", k.cx, ", ", k.cy, ") lies outside the ", width, "x", height,
           " image; the calibration belongs to another image (or the photo is turned)");
  if (velodyne_path.empty()) return l;
  SL_CHECK(l.calibration.has_lidar, "load_kitti_lidar: '", calibration_path,
           "' has no lidar-to-camera transform (lidar2cam or Tr_velo_to_cam), needed for '", velodyne_path, "'");
  l.points = read_velodyne(velodyne_path);
  l.sparse_depth = lidar_depth(l.points, l.calibration);
  for (const glm::vec4& p : l.points) {
    glm::dvec3 cp;
    const glm::dvec3 uvz = project_point(p, l.calibration, &cp);
    if (uvz.z > kMinDepth && std::isfinite(cp.x + cp.y + cp.z)) l.camera_points.push_back(cp);
  }
  return l;
}

KittiFrame load_kitti_frame(const std::string& image_path, const std::string& calibration_path,
                            const std::string& velodyne_path, double camera_height_m) {
  KittiFrame f;
  ImageReadOptions o;
  o.channels = 3;
  o.transfer = Transfer::Linear;
  f.image = read_image(image_path, o).contiguous();
  const int H = static_cast<int>(f.image.size(1)), W = static_cast<int>(f.image.size(2));
  static_cast<KittiLidar&>(f) = load_kitti_lidar(calibration_path, velodyne_path, W, H);
  f.camera = Camera(f.calibration.p2.intrinsics, rotation_from_yaw_pitch_roll(0.0, 0.0, 0.0),
                    glm::dvec3(0.0, camera_height_m, 0.0));
  return f;
}

}  // namespace sl::data
