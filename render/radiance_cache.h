// The radiance cache of object insertion (render/object_insertion.h, "Radiance cache" and
// "Control variate"): Eq. 1 split into the volume's own radiance V(x, l) = Σ τ α G and its
// transmittance τ_K(x, l), queried once per probe and direction, so that
//   L(x, l) = V(x, l) + τ_K(x, l) L_env(l)
// is read per ray trilinearly in position, bilinearly in direction, with L_env exact. Inference
// only (no tape). Internal to render/.
//
// Contract:
// - Probes span the box [lo, hi] (the origins of the rays that will read it), cache_spacing_m
//   apart or sparser: at most max_xz per horizontal axis and max_y vertically, at least 2. An
//   empty box (lo > hi) builds nothing; radiance() then returns 0.
// - Sparse (occupied given): only the corners of grid cells that hold one of `occupied` are
//   marched, so a finer spacing costs the probes the rays' origins need (a surface's shell, not
//   its box). A read whose cell lost corners renormalises over the rest (exact for the origins
//   given: their cells are whole).
// - Directions are the cache_height × cache_width texel centres (render/equirect.h).
// - radiance(o, l) for any o (clamped to the box) and l (zero or non-finite l reads 0).
// - Exact directions (exact_sky > 0): a ray whose sky radiance L_env(l) (largest channel) exceeds
//   exact_sky is marched exactly from its own origin (RayMarcher: the same value radiance_query
//   gives) instead of read from the probes. A sun's transmittance changes faster in space than
//   the probes follow, and its rays carry most of the light (streetlight-bench insert, rows
//   shadow_exact_sky*); the sky's other directions stay cached. Not with build_irradiance().
// - marcher, when given, marches the probes and the exact directions in place of a copy of the
//   volume the cache would build; it must be RayMarcher(in.vsg, in.env, in.grid, opt.query) (the
//   same bits) and outlive the cache.
// - build_irradiance(hn, ss, normals): E(probe, n) = ∫_{n·l>0} (n·l) L_probe(l) dΩ (and the
//   same with (n·l)(1 − n·l)^5 for the control variate's grazing term) for the
//   nodes of an hn × 2·hn grid of normals that bilinear reads of `normals` touch, as a sum over
//   the texels of a grid with ss·max(2·env rows, cache rows) rows of square texels (at least
//   ss × the env's and the cache's columns), each read at its column's centre and its row's
//   solid-angle centroid in elevation (exact for radiance linear in elevation across a row). irradiance(o, n) reads it like radiance(),
//   for n among those normals. With origins (one per normal): only the (probe, node) pairs that
//   irradiance(origins[i], normals[i]) reads are integrated, the same bits for those reads; any
//   other read of E is 0.
// Results do not depend on the thread count.
#pragma once
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/object_insertion.h"
#include "render/radiance_query.h"

namespace sl::render::insertion {

class RadianceCache {
 public:
  RadianceCache(const InsertionInputs& in, const InsertionOptions& opt, const EnvironmentMap& env_map,
                const glm::vec3& lo, const glm::vec3& hi, int max_xz, int max_y, double exact_sky = 0,
                const std::vector<glm::vec3>* occupied = nullptr, const RayMarcher* marcher = nullptr);

  glm::vec3 radiance(const float* origin, const float* dir) const;
  // radiance() at the unit panorama coordinates of a valid direction (no atan2/asin).
  glm::vec3 radiance_unit(const float* origin, const equirect::UV& unit) const;
  // The 8 probes around a point and their trilinear weights, for reading many directions there.
  struct Corners {
    int64_t probe[8];
    float weight[8];
    glm::vec3 origin{0.0f};  // for exact directions
  };
  Corners corners(const float* origin) const;
  glm::vec3 radiance_unit(const Corners& at, const equirect::UV& unit) const;
  // radiance_unit(at, units[i]) into out[i] for i < n, the same bits; the exact directions among
  // them are marched together (RayMarcher's batch).
  void radiance_units(const Corners& at, const equirect::UV* units, int n, glm::vec3* out) const;
  // ∫ (n·l) L dΩ and ∫ (n·l)(1 − n·l)^5 L dΩ over n·l > 0 (the second is Burley's grazing term).
  struct Irradiance {
    glm::vec3 cosine{0.0f}, grazing{0.0f};
  };
  // origins (one per normal), when given: only the probes irradiance(corners(origins[i]),
  // normals[i]) reads are integrated; E of other (probe, node) pairs is left 0.
  void build_irradiance(int hn, int supersample, const std::vector<glm::vec3>& normals,
                        const std::vector<glm::vec3>* origins = nullptr);
  Irradiance irradiance(const glm::vec3& origin, const glm::vec3& n) const;
  Irradiance irradiance(const Corners& at, const glm::vec3& n) const;  // at = corners(origin)
  int64_t probes() const { return cache_.empty() ? 0 : int64_t(dense_of_.size()); }
  int64_t exact_rays() const { return exact_rays_.load(std::memory_order_relaxed); }  // marched so far

 private:
  glm::vec3 cached(const Corners& at, const equirect::UV& unit, const glm::vec3& sky) const;  // the probes' read
  bool exact_direction(const glm::vec3& sky) const { return exact_sky_ > 0.0f && std::max({sky.x, sky.y, sky.z}) > exact_sky_; }
  void probe_weights(const float* origin, int64_t probe[8], float w[8]) const;
  // A normal's four bilinear taps on the normal grid (wn_ × hn_): indices, and which weights are non-zero.
  struct NormalTaps {
    int32_t index[4];
    uint8_t nonzero;  // bit k: weight[k] != 0
    bool valid;       // a finite, non-zero normal
  };
  std::vector<uint8_t> needed_pairs(const std::vector<NormalTaps>& taps, const std::vector<glm::vec3>& origins) const;
  void dense_weights(const float* origin, int64_t probe[8], float w[8]) const;
  glm::vec3 probe(int64_t p) const;

  const EnvironmentMap& env_map_;
  int H_, W_;
  float exact_sky_ = 0.0f;
  std::unique_ptr<const RayMarcher> own_marcher_;  // with exact directions and no marcher given
  const RayMarcher* marcher_ = nullptr;             // with exact directions: the one given or own_marcher_
  mutable std::atomic<int64_t> exact_rays_{0};
  glm::vec3 lo_{0.0f};
  int n_[3] = {2, 2, 2};
  float step_[3] = {1, 1, 1};
  std::vector<int64_t> slot_;      // grid node → built probe (−1: not built); empty: every node, in order
  std::vector<int64_t> dense_of_;  // built probe → grid node
  std::vector<float> cache_;  // [probe][direction][V rgb, τ]
  int hn_ = 0, wn_ = 0;
  std::vector<int64_t> node_row_;  // normal-grid node → row of irradiance_ (−1: not built)
  std::vector<float> irradiance_;   // [kernel][touched normal][probe][rgb]
  int64_t touched_ = 0;
};

// The box of the origins; lo > hi when there are none.
void origin_bounds(const std::vector<glm::vec3>& origins, glm::vec3& lo, glm::vec3& hi);

}  // namespace sl::render::insertion
