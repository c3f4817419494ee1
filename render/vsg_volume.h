// The volumetric spherical Gaussian (VSG) lighting volume of Sec 3.1: its grid, the log
// projection between metric positions and voxel coordinates, and the mapping from raw network
// outputs to valid lobe parameters.
//
// Layout: a VSG tensor is [N, 8, X, Y, Z] (or [8, X, Y, Z] for one scene) with channels
//   0-2 RGB amplitude c (≥ 0), 3-5 lobe axis μ (normalised where used), 6 sharpness λ = 1/σ²,
//   7 alpha α ∈ [0, 1].
// Axes: X ↔ world x and Y ↔ world z (the two horizontal axes, 300 m each by default), Z ↔ world y
// (vertical, 80 m) — so the paper's 256×256×64 and our 64×64×16 keep the vertical axis last.
// The grid is centred on `center` (the camera) and spans [center − extent_neg, center + extent_pos]
// per world axis.
//
// Log projection (per world axis, each side of the centre): s(d) = ±log(1 + |d|/r0) /
// log(1 + h/r0) ∈ [−1, 1] for an offset d ∈ [−h₋, h₊] and voxel coordinate
// (s + 1)/2 · dims, so voxels are ~r0/(dims/2·log(1+h/r0)) near the camera and grow with
// distance. to_metric() inverts it exactly; positions beyond the extent map outside [0, dims].
//
// activate(): raw [.., 8, ..] → parameters: c = softplus(raw), μ = raw (normalised at
// query time with a guarded length), λ = softplus(raw) + kMinSharpness, α = sigmoid(raw). All
// are smooth with bounded derivatives, so gradients stay finite for any raw value.
#pragma once
#include <array>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"

namespace sl::render {

struct VsgGrid {
  std::array<int64_t, 3> dims{64, 64, 16};              // X (world x), Y (world z), Z (world y)
  glm::dvec3 center{0.0, 1.6, 0.0};                     // world position of the grid centre
  glm::dvec3 extent_neg{150.0, 5.0, 150.0};             // world x, y, z extents below the centre
  glm::dvec3 extent_pos{150.0, 75.0, 150.0};            // ... and above
  double log_scale_m = 5.0;                             // r0

  static constexpr double kMinSharpness = 1e-3;

  // World position -> continuous voxel coordinates (X, Y, Z) in [0, dims] inside the grid.
  glm::dvec3 to_voxel(const glm::dvec3& world) const;
  glm::dvec3 to_world(const glm::dvec3& voxel) const;
  bool contains(const glm::dvec3& world) const;
  // Ray parameter interval [t0, t1] inside the grid's box (t0 ≥ 0); false when it misses.
  bool clip_ray(const glm::dvec3& origin, const glm::dvec3& dir, double& t0, double& t1) const;
  void validate() const;  // throws naming the bad field
};

// VsgGrid::to_voxel with the log projection's per-axis denominators log(1 + h/r0) computed once,
// for loops over many points (train/unprojection.cpp): the same value as to_voxel, bit for bit
// (to_voxel is this mapping built for one point). Copies the grid's fields it needs.
class VoxelMapper {
 public:
  explicit VoxelMapper(const VsgGrid& grid);
  glm::dvec3 operator()(const glm::dvec3& world) const;

 private:
  glm::dvec3 center_;
  std::array<double, 3> denom_neg_{}, denom_pos_{}, dims_{};  // per voxel axis
  double r0_;
};

// Raw network output [.., 8, ...] -> VSG parameters (see the header comment). Differentiable.
Tensor vsg_activate(const Tensor& raw, int64_t channel_dim = -4);

}  // namespace sl::render
