// The batched sky draws and densities (render/environment_map_lanes.cpp) equal the scalar ones,
// bit for bit, on maps that exercise every branch of the scalar code.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "render/environment_map.h"
#include "util/random.h"

using sl::render::EnvironmentMap;
namespace equirect = sl::render::equirect;

namespace sl::test {
namespace {

// Maps with a hard sun, black rows and columns (empty cells the searches step over), equal
// neighbours (the inverse CDF's a = b branch), and noise.
std::vector<EnvironmentMap> maps() {
  std::vector<EnvironmentMap> out;
  Tensor noise = Tensor::uniform({3, 16, 32}, 0, 3, 5);
  out.emplace_back(noise);
  Tensor sun = Tensor::ones({3, 32, 64});
  for (int c = 0; c < 3; ++c) sun.data<float>()[(int64_t(c) * 32 + 9) * 64 + 63] = 1e6f;  // at the seam
  out.emplace_back(sun);
  Tensor holes = Tensor::uniform({3, 8, 16}, 0, 1, 9);
  float* h = holes.data<float>();
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 16; ++j)
        if (i < 3 || j % 5 == 2 || (i == 6 && j > 4)) h[(int64_t(c) * 8 + i) * 16 + j] = 0.0f;
  out.emplace_back(holes);
  Tensor lone = Tensor::zeros({3, 4, 8});  // one lit texel: most cells empty
  for (int c = 0; c < 3; ++c) lone.data<float>()[(int64_t(c) * 4 + 3) * 8 + 0] = 2.0f;
  out.emplace_back(lone);
  out.emplace_back(Tensor::zeros({3, 4, 8}));  // black: the uniform sphere
  return out;
}

// u in [0, 1): random, and the edges 0, 1 − ε and exactly 1 (accepted by the contract).
std::vector<float> uniforms(int n, uint64_t seed) {
  const float edges[] = {0.0f, 1.0f, 0.99999994f, 0.5f, 1e-30f, 0.25f};
  std::vector<float> u(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) u[size_t(i)] = i % 7 == 3 ? edges[(i / 7) % 6] : uniform01f(seed, uint64_t(i), 0);
  return u;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(EnvironmentMapLanes, DrawsEqualTheScalarLoop) {
  for (const EnvironmentMap& env : maps())
    for (int n : {1, 7, 8, 9, 16, 33, 1000}) {
      const std::vector<float> u1 = uniforms(n, 11), u2 = uniforms(n, 12);
      std::vector<glm::vec3> d(static_cast<size_t>(n)), ds(static_cast<size_t>(n));
      std::vector<equirect::UV> unit(static_cast<size_t>(n)), units(static_cast<size_t>(n));
      env.sample_bilinear_directions(n, u1.data(), u2.data(), d.data(), unit.data());
      env.sample_bilinear_directions_scalar(n, u1.data(), u2.data(), ds.data(), units.data());
      for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) ASSERT_TRUE(same_bits(d[size_t(i)][c], ds[size_t(i)][c])) << "n " << n << " draw " << i;
        ASSERT_TRUE(same_bits(unit[size_t(i)].u, units[size_t(i)].u))
            << "n " << n << " draw " << i << " map " << env.width() << " u " << u1[size_t(i)] << " " << u2[size_t(i)] << std::hexfloat << " " << unit[size_t(i)].u << " " << units[size_t(i)].u;
        ASSERT_TRUE(same_bits(unit[size_t(i)].v, units[size_t(i)].v)) << "n " << n << " draw " << i;
      }
    }
}

TEST(EnvironmentMapLanes, OutOfRangeUniformsTakeTheScalarPathAlike) {
  const EnvironmentMap env = maps()[0];
  std::vector<float> u1 = uniforms(16, 3), u2 = uniforms(16, 4);
  u1[2] = 1.5f;
  u2[12] = std::nanf("");
  std::vector<glm::vec3> d(16), ds(16);
  std::vector<equirect::UV> unit(16), units(16);
  env.sample_bilinear_directions(16, u1.data(), u2.data(), d.data(), unit.data());
  env.sample_bilinear_directions_scalar(16, u1.data(), u2.data(), ds.data(), units.data());
  for (int i = 0; i < 16; ++i)
    for (int c = 0; c < 3; ++c) ASSERT_TRUE(same_bits(d[size_t(i)][c], ds[size_t(i)][c])) << "draw " << i;
}

TEST(EnvironmentMapLanes, DensitiesEqualTheScalarLoop) {
  for (const EnvironmentMap& env : maps())
    for (int n : {1, 8, 9, 40, 1000}) {
      // The draws' own coordinates, and arbitrary ones: the poles, the seam, beyond one period.
      const std::vector<float> u1 = uniforms(n, 21), u2 = uniforms(n, 22);
      std::vector<glm::vec3> d(static_cast<size_t>(n));
      std::vector<equirect::UV> unit(static_cast<size_t>(n));
      env.sample_bilinear_directions(n, u1.data(), u2.data(), d.data(), unit.data());
      const equirect::UV odd[] = {{0.0, 0.0}, {0.0, 1.0}, {0.9999999, 0.5}, {1.0, 0.5}, {-0.2, 0.3}, {2.5, 0.7},
                                  {0.5, -1e-9}, {1e6, 0.5}, {0.25, 1.0 + 1e-9}};
      for (int i = 0; i < n; i += 5) unit[size_t(i)] = odd[(i / 5) % 9];
      std::vector<double> cos_e(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i) cos_e[size_t(i)] = i % 11 == 4 ? 0.0 : std::sqrt(d[size_t(i)].x * d[size_t(i)].x + d[size_t(i)].z * d[size_t(i)].z);
      for (const double* ce : {static_cast<const double*>(cos_e.data()), static_cast<const double*>(nullptr)}) {
        std::vector<float> p(static_cast<size_t>(n)), ps(static_cast<size_t>(n));
        env.pdf_bilinear_units(n, unit.data(), ce, p.data());
        env.pdf_bilinear_units_scalar(n, unit.data(), ce, ps.data());
        for (int i = 0; i < n; ++i) ASSERT_TRUE(same_bits(p[size_t(i)], ps[size_t(i)])) << "n " << n << " density " << i << ": " << p[size_t(i)] << " vs " << ps[size_t(i)];
      }
    }
}

}  // namespace
}  // namespace sl::test
