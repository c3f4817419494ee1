// Reference path tracer (not differentiable): the ground truth the insertion renderer and the
// analytic cases are checked against (docs/DESIGN.md, "What done means — Correct").
//
// Scene: one triangle Mesh (materials per triangle, glTF metallic-roughness mapped onto the
// Disney BRDF; base-colour textures sampled at the interpolated UV) lit only by an
// EnvironmentMap at infinity. Surfaces are two-sided and opaque; alpha is ignored.
// Estimator: unidirectional path tracing with next-event estimation. At every vertex one
// environment sample (importance-sampled, shadow ray by BVH any-hit) and one BRDF sample are
// combined by multiple importance sampling with the power heuristic (Veach 1997, Ch. 9);
// an environment hit after a BRDF bounce carries the complementary weight. Russian roulette
// from `roulette_depth` bounces on keeps long paths unbiased. With environment_sampling off,
// only BRDF sampling is used (the baseline of `streetlight-bench render`).
// Sample patterns (`estimator`):
//   Stratified (default): every 2D decision of a path — the sub-pixel position, and at each
//     bounce the environment sample, the BRDF direction, the (lobe choice, roulette) pair — is
//     its own Owen-scrambled Sobol pattern (render/qmc_sampler.h), so the first 2^m samples of
//     a pixel are stratified in each of them. The environment is sampled ∝ its bilinear
//     lookup (EnvironmentMap::sample_bilinear), so a sun costs almost no variance. Russian
//     roulette survives with probability min(1, max throughput): a path that still carries
//     full weight is never killed.
//   Independent: the original independent estimator, kept for reproducible comparisons: independent
//     uniform01f(seed, pixel, counter) numbers, the texel environment sampler
//     (EnvironmentMap::sample), survival probability capped at 0.95.
// Both are unbiased and estimate the same image; they differ in noise.
// Determinism: every random number is a pure function of (seed, pixel index, sample, bounce,
// use), so images are bitwise identical for any thread count.
//
// Requires: the Mesh and EnvironmentMap outlive the PathTracer (it keeps references) and the
// Mesh passes validate(); the map is non-empty. Options are validated before any parallel
// region (spp ≥ 1, max_depth ≥ 1, roulette_depth ≥ 1).
// Guarantees: outputs are finite; a non-finite path sample is dropped (counted in
// `nonfinite_samples`, scaled so it counts as black) rather than written.
// Throws: sl::Error naming the option and value, or the invalid mesh / empty map.
#pragma once
#include <cstdint>
#include <memory>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/environment_map.h"
#include "render/mesh.h"

namespace sl::render {

class Camera;  // render/camera.h

// Layout of the random-number counters of one path sample, shared by render() and radiance():
// sample s uses counters [s·stride, (s + 1)·stride) of its pixel's stream.
namespace path_random {
inline constexpr uint64_t kPixelDims = 2;   // sub-pixel jitter
inline constexpr uint64_t kBounceDims = 6;  // environment sample 2, BRDF sample 3, roulette 1
constexpr uint64_t stride(int max_depth) { return kPixelDims + kBounceDims * (max_depth + 1); }
}  // namespace path_random

enum class PathEstimator { Stratified, Independent };

struct PathTracerOptions {
  int spp = 16;              // samples per pixel (jittered inside the pixel)
  // render() computes samples [sample_offset, sample_offset + spp) of each pixel and returns
  // their mean: successive calls with offsets 0, n, 2n, ... continue one stratified sequence
  // (progressive rendering; average the passes weighted by their spp).
  int64_t sample_offset = 0;
  PathEstimator estimator = PathEstimator::Stratified;
  bool exact_fresnel = false;  // disney::Params::exact_fresnel for every material
  int max_depth = 8;         // surface interactions per path; 1 = direct lighting only
  int roulette_depth = 3;    // Russian roulette applies after this many bounces
  uint64_t seed = 0;
  bool environment_sampling = true;  // NEE + MIS; false = BRDF sampling only
  // Validation scenes: shade every surface as Lambertian with its base colour (the analytic
  // cases of docs/DESIGN.md), instead of the Disney BRDF.
  bool lambertian = false;
};

struct PathTracerImage {
  Tensor radiance;  // [3, H, W] F32, linear HDR (the map's units)
  Tensor depth;     // [1, H, W] F32 camera-frame z of the pixel-centre hit (m), 0 where none
  Tensor normal;    // [3, H, W] F32 world shading normal facing the camera, 0 where none
  Tensor mask;      // [1, H, W] F32 1 where the pixel-centre ray hits the mesh
  int64_t nonfinite_samples = 0;
};

class PathTracer {
 public:
  PathTracer(const Mesh& mesh, const EnvironmentMap& environment);
  ~PathTracer();
  PathTracer(const PathTracer&) = delete;
  PathTracer& operator=(const PathTracer&) = delete;

  PathTracerImage render(const Camera& camera, const PathTracerOptions& options) const;

  // One path sample of the radiance arriving at `origin` from `direction` (need not be unit).
  // Random numbers are uniform01f(options.seed, stream, sample·stride + k), as in render().
  glm::vec3 radiance(const glm::vec3& origin, const glm::vec3& direction, uint64_t stream, uint64_t sample,
                     const PathTracerOptions& options) const;

  struct PrimaryHit {
    bool hit = false;
    float distance = 0.0f;     // along the unit direction
    glm::vec3 normal{0.0f};    // shading normal facing the ray origin
  };
  PrimaryHit first_hit(const glm::vec3& origin, const glm::vec3& direction) const;

  // The sub-pixel position in [0, 1)² of sample `sample` of pixel `stream` (the first two
  // random dimensions of the path), for image loops outside render() (e.g. panoramas).
  static glm::vec2 pixel_jitter(uint64_t stream, uint64_t sample, const PathTracerOptions& options);

  static void validate(const PathTracerOptions& options);

 private:
  struct Scene;
  std::unique_ptr<Scene> scene_;
};

}  // namespace sl::render
