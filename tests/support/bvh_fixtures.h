// Meshes, rays and checks shared by the BVH tests (tests/render/bvh_test.cpp, bvh_presplit_test.cpp).
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "render/bvh.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::test {

inline constexpr float kInf = std::numeric_limits<float>::infinity();

inline glm::vec3 random_unit(sl::Rng& rng) {
  const float z = static_cast<float>(rng.uniform(-1.0, 1.0));
  const float phi = static_cast<float>(rng.uniform(0.0, sl::kTwoPi));
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Random triangle soup: many small triangles, some large, some degenerate.
inline sl::render::Mesh random_soup(int count, uint64_t seed) {
  sl::Rng rng(seed);
  sl::render::Mesh m;
  for (int i = 0; i < count; ++i) {
    const glm::vec3 c(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    const float size = i % 50 == 0 ? 0.8f : 0.08f;
    const uint32_t b = static_cast<uint32_t>(m.positions.size());
    for (int k = 0; k < 3; ++k)
      m.positions.push_back(c + size * glm::vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)));
    if (i % 97 == 0) m.positions.back() = m.positions[b];  // degenerate
    m.triangles.push_back({b, b + 1, b + 2});
  }
  return m;
}

inline void expect_matches_brute_force(const sl::render::Mesh& m, const sl::render::Bvh& bvh,
                                const std::vector<sl::render::Ray>& rays) {
  std::vector<sl::render::Hit> hits(rays.size());
  std::vector<uint8_t> occ(rays.size());
  bvh.intersect(rays.data(), hits.data(), rays.size());
  bvh.occluded(rays.data(), occ.data(), rays.size());
  int hit_count = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const sl::render::Hit ref = sl::render::intersect_brute_force(m.positions, m.triangles, rays[i]);
    ASSERT_EQ(hits[i].hit(), ref.hit()) << "ray " << i;
    ASSERT_EQ(occ[i] != 0, ref.hit()) << "ray " << i;
    if (ref.hit()) {
      ++hit_count;
      ASSERT_NEAR(hits[i].t, ref.t, 1e-5f * ref.t) << "ray " << i;
    }
  }
  EXPECT_GT(hit_count, 0);
  EXPECT_LT(hit_count, static_cast<int>(rays.size()));
}

inline std::vector<sl::render::Ray> random_rays(const sl::render::Bounds3& b, int count, uint64_t seed) {
  sl::Rng rng(seed);
  std::vector<sl::render::Ray> rays(count);
  const glm::vec3 c = b.centre(), e = 0.75f * b.extent();
  for (auto& r : rays) {
    r.origin = c + e * glm::vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    r.direction = random_unit(rng);
  }
  return rays;
}

// Traces `rays` with both BVHs (closest and any hit) and checks that every hit is bit-identical;
// returns how many rays hit, or -1 after the first ray that differs.
inline int count_identical_hits(const sl::render::Bvh& x, const sl::render::Bvh& y, const std::vector<sl::render::Ray>& rays) {
  std::vector<sl::render::Hit> a(rays.size()), b(rays.size());
  std::vector<uint8_t> occ_a(rays.size()), occ_b(rays.size());
  x.intersect(rays.data(), a.data(), rays.size());
  y.intersect(rays.data(), b.data(), rays.size());
  x.occluded(rays.data(), occ_a.data(), rays.size());
  y.occluded(rays.data(), occ_b.data(), rays.size());
  int hit_count = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (a[i].triangle != b[i].triangle || a[i].t != b[i].t || a[i].u != b[i].u || a[i].v != b[i].v ||
        occ_a[i] != occ_b[i]) {
      ADD_FAILURE() << "ray " << i << ": triangle " << a[i].triangle << " / " << b[i].triangle << ", t " << a[i].t
                    << " / " << b[i].t << ", u " << a[i].u << " / " << b[i].u << ", v " << a[i].v << " / " << b[i].v
                    << ", occluded " << int(occ_a[i]) << " / " << int(occ_b[i]);
      return -1;
    }
    hit_count += a[i].hit();
  }
  return hit_count;
}

}  // namespace sl::test
