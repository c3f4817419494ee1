// The inner loops' panorama coordinates (render/equirect_lanes.cpp): within 1e-9 of the exact
// ones over the whole sphere (and so within 1e-6 of direction_to_uv), its signed zeros and
// degenerate input mapped alike, and the batch equal to the one-at-a-time form bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "render/equirect.h"
#include "util/random.h"

namespace equirect = sl::render::equirect;

namespace sl::test {
namespace {

// Random directions of every length, and the places atan2 and asin are delicate: the poles
// (approached along every azimuth), the seam φ = ±π (x = ±0 and ±tiny, z > 0), the planes
// x = ±0, y = ±0 and z = ±0, the diagonals |x| = |z| and |y| = √(x² + z²), subnormal components.
std::vector<glm::vec3> directions() {
  std::vector<glm::vec3> out;
  const int random = 1 << 22;
  for (int i = 0; i < random; ++i) {
    glm::vec3 d(2 * uniform01f(7, uint64_t(i), 0) - 1, 2 * uniform01f(7, uint64_t(i), 1) - 1,
                2 * uniform01f(7, uint64_t(i), 2) - 1);
    if (i % 4 == 1) d = glm::normalize(d);
    if (i % 4 == 2) d *= std::pow(10.0f, float(i % 61 - 30));
    out.push_back(d);
  }
  const float small[] = {0.0f, -0.0f, 1e-45f, -1e-45f, 1e-38f, 1e-30f, -1e-20f, 1e-12f, -1e-7f,
                         3e-7f, 1e-5f, -1e-4f, 1e-3f, 0.01f, -0.1f, 0.5f};
  const float big[] = {1.0f, -1.0f, 1e-30f, -3e-5f, 0.7f, 1e30f, -1e30f, 1e-44f};
  for (float a : small)
    for (float b : small)
      for (float c : big) {
        out.emplace_back(a, c, b);  // the poles
        out.emplace_back(a, b, c);  // the seam (c > 0) and φ = 0 (c < 0)
        out.emplace_back(c, a, b);  // φ = ±π/2
        out.emplace_back(a, c, c);  // θ = ±π/4 at the seam's side
      }
  for (int i = 0; i < (1 << 16); ++i) {  // near the poles along every azimuth
    const float phi = float(kTwoPi) * uniform01f(8, uint64_t(i), 0), r = std::pow(10.0f, -8.0f * uniform01f(8, uint64_t(i), 1));
    out.emplace_back(r * std::sin(phi), i % 2 ? 1.0f : -1.0f, -r * std::cos(phi));
  }
  for (int i = 0; i < (1 << 16); ++i) {  // the diagonals
    const float a = 2 * uniform01f(9, uint64_t(i), 0) - 1, s = i % 2 ? 1.0f : -1.0f;
    out.emplace_back(a, s * std::sqrt(2.0f) * std::abs(a), i % 4 < 2 ? a : -a);
  }
  return out;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The exact coordinates, in long double: atan2 of the same two pairs as equirect_lanes.cpp (asin of
// y/|d| is the same angle, but its rounding costs up to 1e-8 rad within 1e-8 of the poles).
equirect::UV exact_unit(const glm::vec3& d) {
  const long double x = d.x, y = d.y, z = d.z, pi = 3.141592653589793238462643383279502884L;
  const long double elevation = std::atan2(y, std::sqrt(x * x + z * z)), azimuth = std::atan2(x, -z);
  return {double(azimuth / (2 * pi) + 0.5L), double(0.5L - elevation / pi)};
}

TEST(EquirectLanes, CoordinatesAreWithin1e9OfTheExactOnes) {
  const std::vector<glm::vec3> d = directions();
  std::vector<equirect::UV> units(d.size());
  equirect::directions_to_units(int(d.size()), d.data(), units.data());
  double max_exact = 0, max_ref = 0, max_ref_exact = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    const equirect::UV exact = exact_unit(d[i]), ref = equirect::direction_to_uv(d[i].x, d[i].y, d[i].z, 1, 1);
    const double e_exact = std::max(std::abs(units[i].u - exact.u), std::abs(units[i].v - exact.v));
    const double e_ref = std::max(std::abs(units[i].u - ref.u), std::abs(units[i].v - ref.v));
    ASSERT_LE(e_exact, 1e-9) << "direction (" << d[i].x << ", " << d[i].y << ", " << d[i].z << "): u " << units[i].u
                             << " vs " << exact.u << ", v " << units[i].v << " vs " << exact.v;
    ASSERT_LE(e_ref, 1e-6) << "direction (" << d[i].x << ", " << d[i].y << ", " << d[i].z << "): u " << units[i].u
                           << " vs " << ref.u << ", v " << units[i].v << " vs " << ref.v;
    max_exact = std::max(max_exact, e_exact), max_ref = std::max(max_ref, e_ref);
    max_ref_exact = std::max({max_ref_exact, std::abs(ref.u - exact.u), std::abs(ref.v - exact.v)});
  }
  std::cout << "over " << d.size() << " directions, max error in u or v: " << max_exact << " (direction_to_uv's "
            << max_ref_exact << "); max difference from direction_to_uv " << max_ref << "\n";
}

TEST(EquirectLanes, SignedZerosAndDegenerateInputMapAsDirectionToUv) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<glm::vec3> d;
  for (float x : {0.0f, -0.0f, 1.0f, inf, -inf, nan})
    for (float y : {0.0f, -0.0f, -2.0f, inf, nan})
      for (float z : {0.0f, -0.0f, 3.0f, -inf, nan}) d.emplace_back(x, y, z);
  std::vector<equirect::UV> units(d.size());
  equirect::directions_to_units(int(d.size()), d.data(), units.data());
  for (size_t i = 0; i < d.size(); ++i) {
    const equirect::UV ref = equirect::direction_to_uv(d[i].x, d[i].y, d[i].z, 1, 1);
    const bool finite = std::isfinite(d[i].x) && std::isfinite(d[i].y) && std::isfinite(d[i].z);
    // Finite: within the bound, on the same side of the seam; otherwise the same bits.
    const double tol = finite ? 1e-9 : 0.0;
    EXPECT_TRUE(std::abs(units[i].u - ref.u) <= tol || same_bits(units[i].u, ref.u))
        << "(" << d[i].x << ", " << d[i].y << ", " << d[i].z << "): u " << units[i].u << " vs " << ref.u;
    EXPECT_TRUE(std::abs(units[i].v - ref.v) <= tol || same_bits(units[i].v, ref.v))
        << "(" << d[i].x << ", " << d[i].y << ", " << d[i].z << "): v " << units[i].v << " vs " << ref.v;
  }
  const equirect::UV zero = equirect::direction_to_unit(-0.0f, 0.0f, -0.0f);
  EXPECT_EQ(zero.u, 0.5);
  EXPECT_EQ(zero.v, 0.5);
}

TEST(EquirectLanes, BatchEqualsTheScalarForm) {
  std::vector<glm::vec3> d = directions();
  for (size_t i = 5; i < d.size(); i += 4099) d[i].y = std::numeric_limits<float>::quiet_NaN();  // a lane group's fallback
  for (int offset : {0, 1, 3})
    for (int n : {1, 7, 8, 9, 17, 1000, int(d.size()) - 3}) {
      std::vector<equirect::UV> units(size_t(n) + 1);
      units[size_t(n)] = {-1.0, -1.0};
      equirect::directions_to_units(n, d.data() + offset, units.data());
      for (int i = 0; i < n; ++i) {
        const glm::vec3& q = d[size_t(offset + i)];
        const equirect::UV one = equirect::direction_to_unit(q.x, q.y, q.z);
        ASSERT_TRUE(same_bits(units[size_t(i)].u, one.u) && same_bits(units[size_t(i)].v, one.v))
            << "n " << n << " offset " << offset << " direction " << i << std::hexfloat << ": (" << units[size_t(i)].u
            << ", " << units[size_t(i)].v << ") vs (" << one.u << ", " << one.v << ")";
      }
      EXPECT_EQ(units[size_t(n)].u, -1.0) << "wrote past n = " << n;
    }
}

}  // namespace
}  // namespace sl::test
