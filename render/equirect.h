// The one equirectangular panorama convention (docs/DESIGN.md, "Panoramas"). Every part calls these.
//
// World frame: right-handed, +Y up. A unit direction d has
//   elevation θ = asin(d.y)          (+π/2 at the zenith)
//   azimuth   φ = atan2(d.x, -d.z)   (0 looking down -Z, +π/2 towards +X)
// An H×W panorama (H = W/2) maps it to continuous pixel coordinates
//   u = W·(φ/2π + 1/2),  v = H·(1/2 - θ/π)
// so row 0 is the zenith, the image centre column looks down -Z, and pixel (i, j) has its centre
// at (u, v) = (j + 0.5, i + 0.5). u wraps at the azimuth seam (φ = ±π, the image's left/right
// edge). Degenerate input (zero vector) maps to the direction's azimuth 0 at elevation 0.
//
// direction_to_uv is the reference (libm's asin and atan2 in double). Inner loops that convert
// millions of directions call direction_to_unit / directions_to_units (render/equirect_lanes.cpp):
// - They give the exact u and v of direction_to_uv(x, y, z, 1, 1) within 1e-9 (4.5e-11 measured
//   over the sphere, poles, seam and axes included: EquirectLanes.* tests), for any finite
//   direction of any length, as θ = atan2(y, √(x² + z²)) and φ = atan2(x, −z) with one minimax
//   arctangent. direction_to_uv's asin of a rounded y/|d| is itself off by up to 7e-9 near the
//   poles, so the two differ by up to that much.
// - Where direction_to_uv's atan2 takes the sign of a zero (x = ±0 on the seam and at the poles)
//   they take it alike; a zero vector maps to (½, ½) and non-finite input to direction_to_uv's
//   own result.
// - The batch equals direction_to_unit bit for bit, in AVX-512 lanes where compiled and one at a
//   time elsewhere, so a direction's coordinates never depend on the batch it came in.
#pragma once
#include <cmath>

#include "util/math.h"

namespace sl::render::equirect {

struct UV {
  double u, v;
};
struct Dir {
  double x, y, z;
};

inline UV direction_to_uv(double x, double y, double z, int width, int height) {
  const double len = std::sqrt(x * x + y * y + z * z);
  if (!(len > 0.0)) return {0.5 * width, 0.5 * height};
  const double ey = std::fmax(-1.0, std::fmin(1.0, y / len));
  const double elevation = std::asin(ey);
  const double azimuth = std::atan2(x, -z);
  return {width * (azimuth / (2.0 * kPi) + 0.5), height * (0.5 - elevation / kPi)};
}

// direction_to_uv(x, y, z, 1, 1) for inner loops, within 1e-9 of exact (see above).
UV direction_to_unit(float x, float y, float z);
// units[i] = direction_to_unit(directions[i]) for i < n, the same bits.
void directions_to_units(int n, const glm::vec3* directions, UV* units);

inline Dir uv_to_direction(double u, double v, int width, int height) {
  const double azimuth = (u / width - 0.5) * 2.0 * kPi;
  const double elevation = (0.5 - v / height) * kPi;
  const double c = std::cos(elevation);
  return {c * std::sin(azimuth), std::sin(elevation), -c * std::cos(azimuth)};
}

// Solid angle of pixel row i of an H×W panorama (sums to 4π over the image).
inline double pixel_solid_angle(int row, int width, int height) {
  const double t0 = (0.5 - static_cast<double>(row) / height) * kPi;
  const double t1 = (0.5 - static_cast<double>(row + 1) / height) * kPi;
  return (2.0 * kPi / width) * (std::sin(t0) - std::sin(t1));
}

}  // namespace sl::render::equirect
