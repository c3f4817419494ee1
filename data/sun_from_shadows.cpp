#include "data/sun_from_shadows.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "data/kitti.h"
#include "util/check.h"
#include "util/math.h"
#include "util/parallel.h"

namespace sl::data {
namespace {

struct Sample {
  glm::dvec3 point;  // world, lifted above the ground
  double x;          // log luminance
  int col, row;
  double xr = 0.0;    // x relative to its level's 75th percentile
  int group = 0;      // 0 road level, 1 raised
  bool dark = false;
};

struct Scene {
  const render::Camera* camera;
  const float* depth;
  int width, height;
  double march_m, thickness_m;
  int march_steps;

  // True when the march from p along s passes behind a surface the depth map shows.
  bool blocked(const glm::dvec3& p, const glm::dvec3& s) const {
    const double t0 = 0.1;
    const double growth = std::pow(march_m / t0, 1.0 / std::max(1, march_steps - 1));
    double t = t0;
    for (int k = 0; k < march_steps; ++k, t *= growth) {
      const render::Projection q = camera->project(p + t * s);
      if (!q.in_image) return false;
      const int col = static_cast<int>(q.pixel.x), row = static_cast<int>(q.pixel.y);
      const float d = depth[static_cast<size_t>(row) * width + col];
      if (!(d > 0.0f) || !std::isfinite(d)) return false;
      const double eps = std::max(0.05, 0.02 * d);
      if (q.depth > d + eps && q.depth < d + thickness_m) return true;
    }
    return false;
  }
};

glm::dvec3 direction_of(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * kPi / 180.0, e = elevation_deg * kPi / 180.0;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

struct Candidate {
  double azimuth_deg = 0.0, elevation_deg = 0.0, score = 0.0;
  int blocked = 0;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  return v[m];
}


int stride_of(const ShadowSunOptions& o, int W, int H) {
  return o.stride_px > 0 ? o.stride_px
                         : std::max(1, static_cast<int>(std::lround(std::sqrt(double(W) * H / 12000.0))));
}

// Every stride-th pixel on the ground (header: "Ground samples"), lifted 2 cm; col/row kept.
std::vector<Sample> ground_samples(const float* img, const float* dep, int W, int H, const render::Camera& camera,
                                   const ShadowSunOptions& o) {
  const size_t plane = static_cast<size_t>(H) * W;
  const int stride = stride_of(o, W, H);
  std::vector<Sample> all;
  std::vector<double> low_y;
  const int rows = (H + stride - 1) / stride, cols = (W + stride - 1) / stride;
  std::vector<int> cell(static_cast<size_t>(rows) * cols, -1);  // index into `all`, −1: no valid depth
  for (int row = 0; row < H; row += stride)
    for (int col = 0; col < W; col += stride) {
      const size_t i = static_cast<size_t>(row) * W + col;
      const float d = dep[i];
      if (!(d > 0.0f) || !std::isfinite(d) || d > o.max_distance_m) continue;
      const double r = img[i], g = img[plane + i], b = img[2 * plane + i];
      if (!std::isfinite(r) || !std::isfinite(g) || !std::isfinite(b)) continue;
      const auto lin = [](double v) { return std::pow(std::clamp(v, 0.0, 1.0), 2.2); };
      const double y = 0.2126 * lin(r) + 0.7152 * lin(g) + 0.0722 * lin(b);
      const glm::dvec3 p = camera.unproject(col + 0.5, row + 0.5, d);
      cell[static_cast<size_t>(row / stride) * cols + col / stride] = static_cast<int>(all.size());
      all.push_back({p, std::log(y + 1e-4), col, row});
      if (p.y < camera.position().y - 1.0) low_y.push_back(p.y);
    }
  std::vector<Sample> ground;
  if (low_y.size() < 16) return ground;
  // Height above the ground: the RANSAC plane of data/kitti.h fitted to the points (camera frame),
  // so a camera pitched against the road does not tilt the ground; the median height of the low
  // points when no plane is found.
  std::vector<glm::dvec3> camera_points;
  camera_points.reserve(all.size());
  for (const Sample& s : all) camera_points.push_back(camera.world_to_camera(s.point));
  const GroundPlane ground_plane = fit_ground_plane(camera_points, 0);
  const double ground_y = median(low_y);
  const auto height_of = [&](size_t k) {
    if (!ground_plane.found) return all[k].point.y - ground_y;
    const glm::dvec3& c = camera_points[k];
    return ground_plane.a * c.x + ground_plane.b * c.z + ground_plane.c - c.y;  // camera y points down
  };
  const Scene cover{&camera, dep, W, H, o.cover_m, o.thickness_m, std::max(8, o.march_steps / 2)};
  // Free-space ground (documented choice): each column is walked from the image's bottom up and
  // stops at the first surface that is not ground. Depth behind a car's windows is often the
  // road seen through the glass (lidar passes through), and such pixels show the car, not the road.
  std::vector<size_t> free_ground;
  // The samples just below the stop at about the stop's depth are dropped too: they are the foot
  // of the obstacle (a bumper, a tyre, a wall's base), a vertical face, not ground.
  for (int c = 0; c < cols; ++c) {
    std::vector<std::pair<int, size_t>> column;  // (cell row, sample)
    for (int r = rows - 1; r >= 0; --r) {
      const int k = cell[static_cast<size_t>(r) * cols + c];
      if (k < 0) continue;
      if (std::abs(height_of(static_cast<size_t>(k))) > o.ground_tolerance_m) {
        const double stop_z = camera_points[static_cast<size_t>(k)].z;
        while (!column.empty() &&
               std::abs(camera_points[column.back().second].z - stop_z) < std::max(0.3, 0.03 * stop_z))
          column.pop_back();
        break;
      }
      column.push_back({r, static_cast<size_t>(k)});
    }
    for (const auto& rk : column) free_ground.push_back(rk.second);
  }
  std::sort(free_ground.begin(), free_ground.end());  // back to row-major order
  for (size_t k : free_ground) {
    const Sample& s = all[k];
    const double above = height_of(k);
    const glm::dvec3 p{s.point.x, s.point.y + 0.02, s.point.z};
    if (cover.blocked(p, {0.0, 1.0, 0.0})) continue;
    Sample g{p, s.x, s.col, s.row};
    g.group = above > o.level_split_m ? 1 : 0;
    ground.push_back(g);
  }
  // Each level (the road; raised ground: sidewalks, curbs) is its own material, so a sample's
  // brightness is measured against its level's 75th percentile (the level's lit ground when at
  // least a quarter of it is lit): xr = x − x_75, and "dark" means xr < −dark_log.
  for (int group = 0; group < 2; ++group) {
    std::vector<double> xs;
    for (const Sample& g : ground)
      if (g.group == group) xs.push_back(g.x);
    if (xs.empty()) continue;
    const size_t k = static_cast<size_t>(0.75 * double(xs.size() - 1));
    std::nth_element(xs.begin(), xs.begin() + static_cast<std::ptrdiff_t>(k), xs.end());
    for (Sample& g : ground)
      if (g.group == group) g.xr = g.x - xs[k], g.dark = g.xr < -o.dark_log;
  }
  return ground;
}

void check_inputs(const Tensor& ldr_in, const Tensor& depth_in, const render::Camera& camera, const ShadowSunOptions& o) {
  SL_CHECK(ldr_in.defined() && ldr_in.dim() == 3 && ldr_in.size(0) == 3, "sun_from_shadows: ldr must be [3, H, W], got ",
           ldr_in.defined() ? ldr_in.describe() : std::string("undefined"));
  const int H = static_cast<int>(ldr_in.size(1)), W = static_cast<int>(ldr_in.size(2));
  SL_CHECK(depth_in.defined() && depth_in.numel() == static_cast<int64_t>(H) * W && depth_in.size(-1) == W &&
               depth_in.size(-2) == H,
           "sun_from_shadows: depth must be [H, W] = [", H, ", ", W, "], got ",
           depth_in.defined() ? depth_in.describe() : std::string("undefined"));
  SL_CHECK(camera.intrinsics().width == W && camera.intrinsics().height == H, "sun_from_shadows: camera is ",
           camera.intrinsics().width, "x", camera.intrinsics().height, " but the image is ", W, "x", H);
  SL_CHECK(o.stride_px >= 0 && o.march_steps >= 2 && o.march_steps <= 4096 && o.march_m > 0.1 && o.thickness_m > 0 &&
               o.coarse_step_deg > 0 && o.fine_step_deg > 0 && o.min_elevation_deg >= 0 &&
               o.max_elevation_deg <= 90 && o.min_elevation_deg <= o.max_elevation_deg && o.refine_seeds >= 1 &&
               o.min_shadow_samples >= 1 && o.ground_tolerance_m > 0 && o.max_distance_m > 0,
           "sun_from_shadows: an option is out of range (stride ", o.stride_px, ", march ", o.march_m, " m in ",
           o.march_steps, " steps, thickness ", o.thickness_m, ", grid ", o.coarse_step_deg, "/", o.fine_step_deg,
           " deg, elevations ", o.min_elevation_deg, "..", o.max_elevation_deg, ")");
}

}  // namespace

ShadowSunFit fit_sun_from_shadows(const Tensor& ldr_in, const Tensor& depth_in, const render::Camera& camera,
                                  const ShadowSunOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  check_inputs(ldr_in, depth_in, camera, o);
  const int H = static_cast<int>(ldr_in.size(1)), W = static_cast<int>(ldr_in.size(2));
  const Tensor ldr = ldr_in.to(DType::F32).contiguous();
  const Tensor depth = depth_in.to(DType::F32).contiguous();
  const float* img = ldr.data<float>();
  const float* dep = depth.data<float>();

  ShadowSunFit fit;
  const std::vector<Sample> samples = ground_samples(img, dep, W, H, camera, o);
  fit.ground_samples = static_cast<int>(samples.size());
  if (samples.size() < 2 * static_cast<size_t>(o.min_shadow_samples)) {
    fit.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return fit;
  }

  const Scene scene{&camera, dep, W, H, o.march_m, o.thickness_m, o.march_steps};
  int dark_total = 0;
  for (const Sample& smp : samples) dark_total += smp.dark;
  const auto score_of = [&](Candidate& c) {
    const glm::dvec3 s = direction_of(c.azimuth_deg, c.elevation_deg);
    int blocked = 0, tp = 0;
    for (const Sample& smp : samples)
      if (scene.blocked(smp.point, s)) ++blocked, tp += smp.dark;
    c.blocked = blocked;
    c.score = 0.0;
    if (blocked < o.min_shadow_samples) return;
    // F_beta of the blocked set against the dark set: beta < 1 weighs precision (a blocked
    // sample that is bright contradicts the direction) above recall (a dark sample the depth
    // map cannot explain may be the shadow of something outside the view).
    const double precision = double(tp) / blocked, recall = dark_total ? double(tp) / dark_total : 0.0;
    const double b2 = o.beta * o.beta;
    c.score = precision + recall > 0 ? (1 + b2) * precision * recall / (b2 * precision + recall) : 0.0;
  };
  const auto score_all = [&](std::vector<Candidate>& cs) {
    parallel_for(static_cast<int64_t>(cs.size()), 1, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) score_of(cs[static_cast<size_t>(i)]);
    });
    fit.candidates += static_cast<int>(cs.size());
  };

  std::vector<Candidate> coarse;
  const int n_az = std::max(1, static_cast<int>(std::lround(360.0 / o.coarse_step_deg)));
  for (double el = o.min_elevation_deg; el <= o.max_elevation_deg + 1e-9; el += o.coarse_step_deg)
    for (int a = 0; a < n_az; ++a) coarse.push_back({-180.0 + a * 360.0 / n_az, el});
  score_all(coarse);
  for (const Candidate& c : coarse) fit.coarse.push_back({c.azimuth_deg, c.elevation_deg, c.score});
  std::vector<size_t> order(coarse.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return coarse[a].score > coarse[b].score; });

  std::vector<Candidate> fine;
  const int half = static_cast<int>(std::floor(o.coarse_step_deg / o.fine_step_deg + 1e-9));
  for (int k = 0; k < o.refine_seeds && k < static_cast<int>(order.size()); ++k) {
    const Candidate& seed = coarse[order[static_cast<size_t>(k)]];
    for (int i = -half; i <= half; ++i)
      for (int j = -half; j <= half; ++j) {
        const double el = seed.elevation_deg + i * o.fine_step_deg;
        if (el < o.min_elevation_deg - 1e-9 || el > o.max_elevation_deg + 1e-9) continue;
        double az = seed.azimuth_deg + j * o.fine_step_deg;
        if (az >= 180.0) az -= 360.0;
        if (az < -180.0) az += 360.0;
        fine.push_back({az, el});
      }
  }
  score_all(fine);
  Candidate best = coarse[order.front()];
  for (const Candidate& c : fine)
    if (c.score > best.score) best = c;

  fit.azimuth_deg = best.azimuth_deg;
  fit.elevation_deg = best.elevation_deg;
  fit.direction = direction_of(best.azimuth_deg, best.elevation_deg);
  fit.score = best.score;
  fit.shadow_samples = best.blocked;
  // A winner on the lowest elevation of the search wants an ever lower sun: its shadows are
  // those of casters whose tops the view does not show (a building's roof edge out of frame),
  // whose height, and so the sun's elevation, the depth cannot tell. Not a fit.
  // Spread: how far from the winner the coarse directions reach that score almost as well.
  for (const Candidate& c : coarse)
    if (c.score >= o.near_best * best.score)
      fit.spread_deg = std::max(fit.spread_deg, std::acos(std::clamp(glm::dot(direction_of(c.azimuth_deg, c.elevation_deg),
                                                                              fit.direction), -1.0, 1.0)) * 180.0 / kPi);
  fit.found = best.score >= o.min_score && best.elevation_deg > o.min_elevation_deg + 0.5 * o.fine_step_deg;
  if (best.blocked > 0) {
    std::vector<double> xs, xl;
    for (const Sample& smp : samples) {
      const bool blocked = scene.blocked(smp.point, fit.direction);
      if (blocked && smp.dark) xs.push_back(smp.xr);
      if (!blocked) xl.push_back(smp.xr);
    }
    if (!xs.empty() && !xl.empty()) fit.shadow_ratio = std::exp(median(xs) - median(xl));
  }
  fit.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return fit;
}

}  // namespace sl::data

namespace sl::data {

Tensor shadow_sun_mask(const Tensor& ldr_in, const Tensor& depth_in, const render::Camera& camera,
                       const glm::dvec3& sun_direction, const ShadowSunOptions& o) {
  check_inputs(ldr_in, depth_in, camera, o);
  const int H = static_cast<int>(ldr_in.size(1)), W = static_cast<int>(ldr_in.size(2));
  const Tensor ldr = ldr_in.to(DType::F32).contiguous();
  const Tensor depth = depth_in.to(DType::F32).contiguous();
  const std::vector<Sample> samples = ground_samples(ldr.data<float>(), depth.data<float>(), W, H, camera, o);
  const Scene scene{&camera, depth.data<float>(), W, H, o.march_m, o.thickness_m, o.march_steps};
  const glm::dvec3 s = glm::normalize(sun_direction);
  const int stride = stride_of(o, W, H);
  Tensor mask = Tensor::zeros({1, H, W});
  float* m = mask.data<float>();
  parallel_for(static_cast<int64_t>(samples.size()), 256, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const Sample& smp = samples[static_cast<size_t>(i)];
      const float v = scene.blocked(smp.point, s) ? 1.0f : 0.5f;
      for (int r = smp.row; r < std::min(H, smp.row + stride); ++r)
        for (int c = smp.col; c < std::min(W, smp.col + stride); ++c) m[static_cast<size_t>(r) * W + c] = v;
    }
  });
  return mask;
}

}  // namespace sl::data
