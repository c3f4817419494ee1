// BVH pre-splits (render/bvh.h, BvhBuildOptions::split_budget): the same hits with and without
// them, rays exactly on the split planes, and a tree independent of the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>

#include "render/bvh.h"
#include "support/bvh_fixtures.h"
#include "util/random.h"

namespace sl::test {

namespace {

// Thin slivers in random orientations, overlapping, plus a few large triangles: the triangles
// pre-splits are for (their boxes are far larger than their areas).
sl::render::Mesh slivers(int count, uint64_t seed) {
  sl::Rng rng(seed);
  sl::render::Mesh m;
  for (int i = 0; i < count; ++i) {
    const glm::vec3 p(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    const float len = i % 100 == 0 ? 1.5f : static_cast<float>(rng.uniform(0.05, 0.4));
    const glm::vec3 d = random_unit(rng), w = 0.01f * len * glm::normalize(glm::cross(d, random_unit(rng)));
    const uint32_t b = static_cast<uint32_t>(m.positions.size());
    m.positions.insert(m.positions.end(), {p, p + len * d + w, p + len * d - w});
    m.triangles.push_back({b, b + 1, b + 2});
  }
  return m;
}

sl::render::BvhBuildOptions split_budget(float budget) {
  sl::render::BvhBuildOptions o;
  o.split_budget = budget;
  return o;
}

// Pre-splits (bvh.h) give some triangles several leaf slots; queries must not change: the same
// hits as brute force, and bit-identical hits to the tree built without them.
TEST(Bvh, PreSplitsMatchBruteForceAndTheUnsplitTree) {
  const sl::render::Mesh m = slivers(8000, 71);
  const sl::render::Bvh plain(m, split_budget(0.0f));
  EXPECT_EQ(plain.reference_count(), plain.triangle_count());
  for (const float budget : {1.0f, 4.0f}) {
    SCOPED_TRACE(budget);
    sl::render::Bvh split(m, split_budget(budget));
    EXPECT_EQ(split.triangle_count(), plain.triangle_count());
    EXPECT_GT(split.reference_count(), plain.reference_count());
    EXPECT_LE(split.reference_count(), static_cast<size_t>((1.0f + budget) * plain.triangle_count()) + 1);
    expect_matches_brute_force(m, split, random_rays(m.bounds(), 1500, 73));
    const std::vector<sl::render::Ray> rays = random_rays(m.bounds(), 4000, 79);
    for (const bool portable : {false, true}) {
      split.use_portable_kernels(portable);
      std::vector<sl::render::Hit> a(rays.size()), b(rays.size());
      std::vector<uint8_t> occ_a(rays.size()), occ_b(rays.size());
      split.intersect(rays.data(), a.data(), rays.size());
      plain.intersect(rays.data(), b.data(), rays.size());
      split.occluded(rays.data(), occ_a.data(), rays.size());
      plain.occluded(rays.data(), occ_b.data(), rays.size());
      for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_EQ(a[i].t, b[i].t) << "ray " << i;  // +inf on both for a miss
        ASSERT_EQ(occ_a[i], occ_b[i]) << "ray " << i;
      }
    }
  }
}

// A reference's box holds only its part of the triangle, cut at grid planes through the mesh's
// box; rays that hit a split triangle exactly on or beside such a plane must still find it.
TEST(Bvh, RaysThroughPreSplitPlanesHitTheSplitTriangle) {
  sl::render::Mesh m = slivers(3000, 83);
  // A large tilted quad across the whole box, far from the slivers (y in [3, 4]).
  const uint32_t b = static_cast<uint32_t>(m.positions.size());
  m.positions.insert(m.positions.end(), {{-1.1f, 3.0f, -1.1f}, {1.1f, 3.5f, -1.1f}, {1.1f, 4.0f, 1.1f}, {-1.1f, 3.5f, 1.1f}});
  m.triangles.push_back({b, b + 1, b + 2});
  m.triangles.push_back({b, b + 2, b + 3});
  const sl::render::Bvh bvh(m, split_budget(2.0f));
  ASSERT_GT(bvh.reference_count(), bvh.triangle_count());
  const sl::render::Bounds3 box = bvh.bounds();
  std::vector<sl::render::Ray> rays;
  for (int level = 1; level <= 4; ++level)
    for (int k = 1; k < (1 << level); ++k)
      for (int axis : {0, 2}) {
        // The grid plane x (or z) = lo + k·extent/2^level, and its float neighbours.
        const float plane = box.lo[axis] + std::ldexp(box.hi[axis] - box.lo[axis], -level) * static_cast<float>(k);
        if (!(std::abs(plane) < 1.09f)) continue;  // outside the quad
        for (const float c : {std::nextafter(plane, -kInf), plane, std::nextafter(plane, kInf)})
          for (int j = 0; j < 9; ++j) {
            sl::render::Ray r;
            const float other = -1.05f + 2.1f * static_cast<float>(j) / 8.0f;
            r.origin = axis == 0 ? glm::vec3(c, 10.0f, other) : glm::vec3(other, 10.0f, c);
            r.direction = glm::vec3(0.0f, -1.0f, 0.0f);
            rays.push_back(r);
          }
      }
  for (size_t i = 0; i < rays.size(); ++i) {
    const sl::render::Hit ref = sl::render::intersect_brute_force(m.positions, m.triangles, rays[i]);
    ASSERT_TRUE(ref.hit()) << "ray " << i;
    const sl::render::Hit hit = bvh.intersect(rays[i]);
    ASSERT_TRUE(hit.hit()) << "ray " << i;
    EXPECT_EQ(hit.t, ref.t) << "ray " << i;
    EXPECT_TRUE(bvh.occluded(rays[i])) << "ray " << i;
  }
}

TEST(Bvh, PreSplitTreeDoesNotDependOnThreadCount) {
  const sl::render::Mesh m = slivers(40000, 89);  // above the parallel build threshold
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const sl::render::Bvh one(m, split_budget(1.0f));
  omp_set_num_threads(2);
  const sl::render::Bvh two(m, split_budget(1.0f));
  omp_set_num_threads(threads);
  ASSERT_EQ(one.reference_count(), two.reference_count());
  ASSERT_EQ(one.node_count(), two.node_count());
  for (size_t i = 0; i < one.node_count(); ++i)
    for (int c = 0; c < sl::render::BvhNode::kWidth; ++c) {
      ASSERT_EQ(one.nodes()[i].child[c], two.nodes()[i].child[c]);
      for (int a = 0; a < 6; ++a) ASSERT_EQ(one.nodes()[i].bounds[a][c], two.nodes()[i].bounds[a][c]);
    }
}

}  // namespace

}  // namespace sl::test
