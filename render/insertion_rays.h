// Pieces shared by the two halves of object insertion (render/insertion_foreground.h, Eq. 2,
// and render/insertion_shadows.h, Eq. 3-4): the seeds and stratified sample patterns of light
// and shadow rays, the fixed-slot ray buffer both fill for the one radiance query, and the
// screen and box bounds that prune what the object cannot affect. Internal to render/.
//
// Contract: every function is pure; a sample is a function of (seed, stream, index) only, so
// the rays are the same for any thread count (util/random.h).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "render/bvh.h"
#include "render/camera.h"
#include "render/environment_map.h"
#include "render/object_insertion.h"
#include "util/check.h"
#include "util/random.h"

namespace sl::render::insertion {

inline constexpr uint64_t kTagAa = 0xA11A5EEDull, kTagLight = 0x11647ull, kTagShadow = 0x5AD0Eull, kTagChoice = 0xC401CEull;

inline constexpr uint64_t kTagRotation = 0x2071A7Eull, kTagAdaptive = 0xADA97ull, kTagExact = 0xE8AC7ull;

inline bool valid_depth(double d) { return std::isfinite(d) && d > 0.0; }

// The seed of one family of light/shadow samples; lighting_seed = 0 leaves the seeds of
// earlier versions unchanged (the trainer's bits do not move).
inline uint64_t sample_seed(const InsertionOptions& opt, uint64_t tag) {
  const uint64_t base = hash_counter(opt.seed, tag);
  return opt.lighting_seed == 0 ? base : hash_counter(base, opt.lighting_seed);
}

inline float radical_inverse2(uint32_t i) {
  i = (i << 16) | (i >> 16);
  i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
  i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
  i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
  i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
  return float(i) * 0x1.0p-32f;
}

inline float wrap01(float x) {
  x -= std::floor(x);
  return x < 1.0f ? x : 0.0f;
}

// Point j of an m-point Hammersley set, shifted by (r1, r2) modulo 1 (Cranley-Patterson):
// stratified in both coordinates, and unbiased because the shift is uniform.
inline glm::vec2 rotated_hammersley(int j, int m, float r1, float r2) {
  return {wrap01((float(j) + 0.5f) / float(m) + r1), wrap01(radical_inverse2(uint32_t(j)) + r2)};
}

// Inference: sample k of n goes to technique 0 (k < n0) or 1, and is point j of its technique's
// stratified set; the rotation is per stream and technique. With `subs` > 1, `subs` callers
// (sub = 0 … subs − 1, e.g. the anti-aliasing samples of one pixel) share the stream and its
// rotation and take interleaved points j·subs + sub of one set `subs` times larger: each point
// is still uniform (unbiased), and together they are stratified `subs` times finer.
struct SplitSample {
  int technique;
  glm::vec2 u;
};
// The per-stream rotations of both techniques (r1, r2 of technique 0, then of technique 1).
struct SplitRotations {
  float r[4];
};
inline SplitRotations split_rotations(uint64_t rot_seed, uint64_t stream) {
  return {{uniform01f(rot_seed, stream, 0), uniform01f(rot_seed, stream, 1), uniform01f(rot_seed, stream, 2),
           uniform01f(rot_seed, stream, 3)}};
}
inline SplitSample split_sample(const SplitRotations& rot, int k, int n, int n0, int sub = 0, int subs = 1) {
  const int technique = k < n0 ? 0 : 1, j = technique == 0 ? k : k - n0, m = technique == 0 ? n0 : n - n0;
  return {technique, rotated_hammersley(j * subs + sub, m * subs, rot.r[2 * technique], rot.r[2 * technique + 1])};
}
inline SplitSample split_sample(uint64_t rot_seed, uint64_t stream, int k, int n, int n0, int sub = 0, int subs = 1) {
  const int technique = k < n0 ? 0 : 1, j = technique == 0 ? k : k - n0, m = technique == 0 ? n0 : n - n0;
  const float r1 = uniform01f(rot_seed, stream, 2 * technique), r2 = uniform01f(rot_seed, stream, 2 * technique + 1);
  return {technique, rotated_hammersley(j * subs + sub, m * subs, r1, r2)};
}
// The environment technique of inference sampling (InsertionOptions::bilinear_env_sampling).
inline glm::vec3 env_sample(const EnvironmentMap& env, const InsertionOptions& opt, float u1, float u2) {
  return opt.bilinear_env_sampling ? env.sample_bilinear_direction(u1, u2) : env.sample(u1, u2).direction;
}
inline float env_pdf(const EnvironmentMap& env, const InsertionOptions& opt, const glm::vec3& d) {
  return opt.bilinear_env_sampling ? env.pdf_bilinear(d) : env.pdf(d);
}

inline float ray_epsilon(const glm::vec3& p) { return 1e-3f + 1e-4f * glm::length(p); }

// Rays leaving the object or the ground, in a fixed layout (slot i is written by one thread).
struct QueryRays {
  std::vector<float> origin, dir;  // 3 per ray
  void resize(int64_t n) {
    origin.assign(size_t(3 * n), 0.0f);
    dir.assign(size_t(3 * n), 0.0f);
  }
  void set(int64_t i, const glm::vec3& o, const glm::vec3& d) {
    SL_DASSERT(i >= 0 && i < size(), "QueryRays::set: slot ", i, " outside [0, ", size(), ")");
    for (int c = 0; c < 3; ++c) {
      origin[size_t(3 * i + c)] = o[c];
      dir[size_t(3 * i + c)] = d[c];
    }
  }
  int64_t size() const { return int64_t(origin.size() / 3); }
};

// Pixel rectangle [x0, x1) × [y0, y1) that the object's box covers (the whole image when a
// corner is behind the camera, or when pruning is off).
struct Rect {
  int x0, y0, x1, y1;
  int64_t area() const { return int64_t(std::max(0, x1 - x0)) * std::max(0, y1 - y0); }
};

inline Rect screen_bounds(const Bounds3& b, const Camera& cam, bool prune) {
  const int W = cam.intrinsics().width, H = cam.intrinsics().height;
  if (!prune) return {0, 0, W, H};
  double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? b.hi.x : b.lo.x, (c & 2) ? b.hi.y : b.lo.y, (c & 4) ? b.hi.z : b.lo.z);
    const Projection pr = cam.project(p);
    if (!pr.in_front) return {0, 0, W, H};
    u0 = std::min(u0, pr.pixel.x);
    u1 = std::max(u1, pr.pixel.x);
    v0 = std::min(v0, pr.pixel.y);
    v1 = std::max(v1, pr.pixel.y);
  }
  return {std::clamp(int(std::floor(u0)), 0, W), std::clamp(int(std::floor(v0)), 0, H),
          std::clamp(int(std::ceil(u1)) + 1, 0, W), std::clamp(int(std::ceil(v1)) + 1, 0, H)};
}

inline bool ray_hits_box(const glm::vec3& o, const glm::vec3& d, const Bounds3& b) {
  float t0 = 0.0f, t1 = 1e30f;
  for (int a = 0; a < 3; ++a) {
    const float inv = 1.0f / d[a];
    float ta = (b.lo[a] - o[a]) * inv, tb = (b.hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, std::isnan(ta) ? t0 : ta);
    t1 = std::min(t1, std::isnan(tb) ? t1 : tb);
  }
  return t0 <= t1;
}

}  // namespace sl::render::insertion
