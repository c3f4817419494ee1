// BVH queries against brute force, plus the edge cases the header promises.
#include <algorithm>

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <filesystem>

#include "render/bvh.h"
#include "render/gltf_loader.h"
#include "support/bvh_fixtures.h"
#include "util/math.h"
#include "util/random.h"

using sl::render::Bvh;

namespace sl::test {

namespace {

TEST(Bvh, ClosestHitMatchesBruteForceOnRandomSoup) {
  const sl::render::Mesh m = random_soup(3000, 7);
  const sl::render::Bvh bvh(m);
  EXPECT_LT(bvh.triangle_count(), m.triangle_count());  // degenerate triangles were left out
  expect_matches_brute_force(m, bvh, random_rays(m.bounds(), 2000, 11));
}

TEST(Bvh, VectorTestsGiveBitIdenticalHitsToTheScalarTest) {
  // The 8-wide box and triangle tests must reproduce the scalar test of intersect_brute_force
  // operation for operation: the same t, u and v to the bit, not just close. A closed bumpy
  // surface of small triangles plus a random soup, rays from inside and outside.
  sl::render::Mesh m = random_soup(4000, 31);
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) {
      const uint32_t b = static_cast<uint32_t>(m.positions.size());
      auto p = [](int i, int j) {
        const float x = -1.5f + i * 0.05f, z = -1.5f + j * 0.05f;
        return glm::vec3(x, 0.1f * std::sin(7.0f * x) * std::cos(5.0f * z), z);
      };
      m.positions.insert(m.positions.end(), {p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)});
      m.triangles.push_back({b, b + 1, b + 2});
      m.triangles.push_back({b, b + 2, b + 3});
    }
  const sl::render::Bvh bvh(m);
  const auto rays = random_rays(m.bounds(), 2000, 37);
  std::vector<sl::render::Hit> hits(rays.size());
  bvh.intersect(rays.data(), hits.data(), rays.size());
  int hit_count = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const sl::render::Hit ref = sl::render::intersect_brute_force(m.positions, m.triangles, rays[i]);
    ASSERT_EQ(hits[i].hit(), ref.hit()) << "ray " << i;
    if (!ref.hit()) continue;
    ++hit_count;
    ASSERT_EQ(hits[i].t, ref.t) << "ray " << i;
    if (hits[i].triangle == ref.triangle) {  // else two triangles at the same t, e.g. a shared edge
      EXPECT_EQ(hits[i].u, ref.u) << "ray " << i;
      EXPECT_EQ(hits[i].v, ref.v) << "ray " << i;
    }
  }
  EXPECT_GT(hit_count, 300);
}

TEST(Bvh, PortableAndVectorKernelsGiveBitIdenticalHits) {
  // The portable lane loops are the fallback for machines without AVX2; forced at run time here,
  // they must give what the vector tests give, to the bit, closest and any hit alike.
  const sl::render::Mesh m = random_soup(6000, 51);
  const sl::render::Bvh vector_bvh(m);
  sl::render::Bvh portable_bvh(m);
  portable_bvh.use_portable_kernels(true);
  ASSERT_TRUE(portable_bvh.uses_portable_kernels());
  ASSERT_FALSE(vector_bvh.uses_portable_kernels());
  std::vector<sl::render::Ray> rays = random_rays(m.bounds(), 3000, 53);
  sl::Rng rng(55);
  for (size_t i = 0; i < rays.size(); i += 3) {
    rays[i].tmin = static_cast<float>(rng.uniform(0.0, 0.3));
    rays[i].tmax = rays[i].tmin + static_cast<float>(rng.uniform(0.0, 1.0));
  }
  const int hit_count = count_identical_hits(vector_bvh, portable_bvh, rays);
  EXPECT_GT(hit_count, 300);
  EXPECT_LT(hit_count, static_cast<int>(rays.size()));
  // With prefetching (trees larger than the L2 cache), AVX-512 tests a leaf over two blocks in one
  // 16-wide pass.
  sl::render::Bvh prefetching_bvh(m);
  prefetching_bvh.use_prefetch(true);
  EXPECT_EQ(count_identical_hits(prefetching_bvh, portable_bvh, rays), hit_count);
}

TEST(Bvh, KernelsVisitChildrenAtEqualDistancesInTheSameOrder) {
  // Copies of one triangle have equal boxes and hit at exactly the same t, so the copy reported
  // is the first one visited: the vector kernels' ordering of children (a sorting network under
  // AVX-512) must break ties as the portable insertion sort does, for two children (24 copies: a
  // root of two leaves) and for more (200), at entry distances 0 (origins inside the boxes) and
  // negative (the same rays with tmin = −∞).
  for (const int copies : {24, 200}) {
    sl::render::Mesh m;
    m.positions = {{-1.0f, -0.5f, -1.0f}, {1.0f, -0.5f, -1.0f}, {0.0f, 0.5f, 1.0f}};
    m.triangles.assign(static_cast<size_t>(copies), glm::uvec3(0, 1, 2));
    const sl::render::Bvh vector_bvh(m);
    sl::render::Bvh portable_bvh(m);
    portable_bvh.use_portable_kernels(true);
    sl::Rng rng(71);
    std::vector<sl::render::Ray> rays;
    for (int i = 0; i < 300; ++i) {
      float u = static_cast<float>(rng.uniform(0.05, 0.95)), v = static_cast<float>(rng.uniform(0.05, 0.95));
      if (u + v > 1.0f) u = 1.0f - u, v = 1.0f - v;  // inside the triangle
      const glm::vec3 target = (1.0f - u - v) * m.positions[0] + u * m.positions[1] + v * m.positions[2];
      sl::render::Ray r;
      r.origin = target + glm::vec3(rng.uniform(-0.1, 0.1), 0.2f, rng.uniform(-0.1, 0.1));
      r.direction = target - r.origin;  // the hit at t = 1
      if (i % 2) r.tmin = -kInf;
      rays.push_back(r);
    }
    EXPECT_EQ(count_identical_hits(vector_bvh, portable_bvh, rays), 300) << copies << " copies";
    // Leaves of more than 8 copies span two blocks: with prefetching (the traversal of trees larger
    // than the L2 cache) AVX-512 tests both at once, and must still report the first copy.
    sl::render::Bvh prefetching_bvh(m);
    prefetching_bvh.use_prefetch(true);
    EXPECT_EQ(count_identical_hits(prefetching_bvh, portable_bvh, rays), 300) << copies << " copies, prefetching";
  }
}

TEST(Bvh, PrefetchingDoesNotChangeHits) {
  // The build turns prefetching on only for trees larger than the L2 cache, so the small test
  // meshes would otherwise never run that traversal; both must give the same hits.
  const sl::render::Mesh m = random_soup(6000, 57);
  for (const bool portable : {false, true}) {
    sl::render::Bvh with(m), without(m);
    with.use_portable_kernels(portable), without.use_portable_kernels(portable);
    with.use_prefetch(true), without.use_prefetch(false);
    ASSERT_TRUE(with.uses_prefetch());
    ASSERT_FALSE(without.uses_prefetch());
    const std::vector<sl::render::Ray> rays = random_rays(m.bounds(), 3000, 59);
    EXPECT_GT(count_identical_hits(with, without, rays), 300);
  }
  expect_matches_brute_force(m, [&] {
    sl::render::Bvh b(m);
    b.use_prefetch(true);
    return b;
  }(), random_rays(m.bounds(), 500, 61));
}

TEST(Bvh, RaysWithTiedDirectionComponentsMatchBruteForce) {
  // The ray set-up picks the dominant axis of |d| without branches; ties (|dx| = |dy|, diagonals,
  // zero components) and every sign must still give the scalar test's hits.
  const sl::render::Mesh m = random_soup(2000, 41);
  const sl::render::Bvh bvh(m);
  sl::Rng rng(43);
  std::vector<sl::render::Ray> rays;
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        for (int k = 0; k < 40; ++k) {
          sl::render::Ray r;
          r.origin = glm::vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
          r.direction = glm::vec3(dx, dy, dz) * static_cast<float>(rng.uniform(0.5, 2.0));
          rays.push_back(r);
        }
      }
  expect_matches_brute_force(m, bvh, rays);
  std::vector<sl::render::Hit> hits(rays.size());
  bvh.intersect(rays.data(), hits.data(), rays.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    const sl::render::Hit ref = sl::render::intersect_brute_force(m.positions, m.triangles, rays[i]);
    EXPECT_EQ(hits[i].t, ref.t) << "ray " << i;
  }
}

TEST(Bvh, ClosestHitRespectsTminAndTmax) {
  const sl::render::Mesh m = random_soup(500, 3);
  const sl::render::Bvh bvh(m);
  std::vector<sl::render::Ray> rays = random_rays(m.bounds(), 1000, 5);
  sl::Rng rng(9);
  for (auto& r : rays) {
    r.tmin = static_cast<float>(rng.uniform(0.0, 0.5));
    r.tmax = r.tmin + static_cast<float>(rng.uniform(0.0, 1.0));
  }
  expect_matches_brute_force(m, bvh, rays);
}

// A tmin below 0 is read as 0 (render/bvh.h): a flat (zero-thickness box) triangle and a tilted
// one behind the origin are never hit, with or without the vector kernels, and one in front is.
TEST(Bvh, NegativeTminSearchesFromTheOrigin) {
  sl::render::Mesh m;
  m.positions = {{-1, -1, -2}, {1, -1, -2}, {0, 1, -2},            // flat, behind (z = -2)
                 {-1, -1, -3}, {1, -1, -3.5f}, {0, 1, -3.2f},      // tilted, behind
                 {-1, -1, 4}, {1, -1, 4}, {0, 1, 4}};              // flat, in front (z = 4)
  m.triangles = {{0, 1, 2}, {3, 4, 5}, {6, 7, 8}};
  for (const bool portable : {false, true}) {
    sl::render::Bvh bvh(m);
    bvh.use_portable_kernels(portable);
    sl::render::Ray r;
    r.origin = {0.1f, 0.0f, 0.0f};
    r.direction = {0.0f, 0.0f, 1.0f};
    r.tmin = -10.0f;
    const sl::render::Hit h = bvh.intersect(r);
    ASSERT_TRUE(h.hit());
    EXPECT_EQ(h.triangle, 2u);
    EXPECT_FLOAT_EQ(h.t, 4.0f);
    EXPECT_EQ(sl::render::intersect_brute_force(m.positions, m.triangles, r).triangle, 2u);
    r.origin = {0.1f, 0.0f, 5.0f};  // everything it could hit lies at t < 0
    r.tmin = -100.0f;
    EXPECT_FALSE(bvh.intersect(r).hit()) << "portable " << portable;
    EXPECT_FALSE(bvh.occluded(r));
    EXPECT_FALSE(sl::render::intersect_brute_force(m.positions, m.triangles, r).hit());
    r.origin = {0.1f, 0.0f, 0.0f};
    r.tmax = 3.0f;
    EXPECT_FALSE(bvh.occluded(r));  // the only hit ahead is at t = 4
    r.tmax = 5.0f;
    EXPECT_TRUE(bvh.occluded(r));
  }
}

TEST(Bvh, SharedEdgeIsWatertight) {
  // Two triangles sharing the diagonal of the unit square; rays aimed exactly at the diagonal.
  sl::render::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  const sl::render::Bvh bvh(m);
  for (int i = 1; i < 1000; ++i) {
    const float s = i / 1000.0f;
    sl::render::Ray r;
    r.origin = {s, s, 1.0f};
    r.direction = {0.0f, 0.0f, -1.0f};
    EXPECT_TRUE(bvh.intersect(r).hit()) << s;
    r.origin = {s + 0.3f, s - 0.2f, 2.0f};  // oblique rays through the diagonal point (s, s, 0)
    r.direction = glm::vec3(s, s, 0.0f) - r.origin;
    EXPECT_TRUE(bvh.intersect(r).hit()) << s;
  }
}

TEST(Bvh, RaysThroughTheSharedVertexOfAFanAlwaysHit) {
  // 40 triangles around one vertex: leaves are full, and a ray through the centre gives exact
  // zero edge functions in many lanes of one block at once; along a spoke, in two lanes.
  constexpr int kSpokes = 40;
  sl::render::Mesh m;
  m.positions.push_back({0.25f, 0.5f, 0.0f});
  for (int i = 0; i < kSpokes; ++i) {
    const float a = (2.0f * sl::kPiF) * i / kSpokes;
    m.positions.push_back({0.25f + std::cos(a), 0.5f + std::sin(a), 0.1f * std::sin(3.0f * a)});
  }
  for (uint32_t i = 0; i < kSpokes; ++i) m.triangles.push_back({0, 1 + i, 1 + (i + 1) % kSpokes});
  const sl::render::Bvh bvh(m);
  sl::Rng rng(6);
  for (int k = 0; k < 500; ++k) {
    const glm::vec3 target = k % 2 == 0 ? m.positions[0]
                                        : glm::mix(m.positions[0], m.positions[1 + (k / 2) % kSpokes],
                                                   static_cast<float>(rng.uniform(0.0, 1.0)));
    sl::render::Ray r;
    r.origin = target + glm::vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), 2.0f);
    r.direction = target - r.origin;
    EXPECT_TRUE(bvh.intersect(r).hit()) << k;
    EXPECT_TRUE(bvh.occluded(r)) << k;
    EXPECT_EQ(bvh.intersect(r).hit(), sl::render::intersect_brute_force(m.positions, m.triangles, r).hit()) << k;
  }
}

TEST(Bvh, DegenerateTrianglesAreNeverHit) {
  sl::render::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  m.triangles = {{0, 1, 2}, {3, 4, 3}};  // collinear, then a point
  const sl::render::Bvh bvh(m);
  EXPECT_TRUE(bvh.empty());
  sl::render::Ray r;
  r.origin = {1, 1, 0};
  r.direction = {0, -1, 0};
  EXPECT_FALSE(bvh.intersect(r).hit());
  EXPECT_FALSE(sl::render::intersect_brute_force(m.positions, m.triangles, r).hit());
}

TEST(Bvh, RayInTheTrianglePlaneMissesIt) {
  sl::render::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  const sl::render::Bvh bvh(m);
  sl::render::Ray r;
  r.origin = {-1, 0.2f, 0};
  r.direction = {1, 0, 0};  // slides along z = 0 across the triangle
  EXPECT_FALSE(bvh.intersect(r).hit());
  EXPECT_FALSE(bvh.occluded(r));
}

TEST(Bvh, RayLeavingASurfaceWithEpsilonTminDoesNotSelfHit) {
  const sl::render::Mesh m = random_soup(2000, 21);
  const sl::render::Bvh bvh(m);
  sl::Rng rng(4);
  int tested = 0;
  for (size_t t = 0; t < m.triangle_count(); t += 3) {
    const glm::uvec3 tri = m.triangles[t];
    const glm::vec3 p0 = m.positions[tri.x], p1 = m.positions[tri.y], p2 = m.positions[tri.z];
    const glm::vec3 n = glm::cross(p1 - p0, p2 - p0);
    if (glm::length(n) < 1e-6f) continue;
    const float u = static_cast<float>(rng.uniform(0.05, 0.45)), v = static_cast<float>(rng.uniform(0.05, 0.45));
    sl::render::Ray r;
    r.origin = (1 - u - v) * p0 + u * p1 + v * p2;
    r.direction = random_unit(rng);
    r.tmin = 1e-4f;
    const sl::render::Hit h = bvh.intersect(r);
    if (h.hit()) {
      EXPECT_NE(h.triangle, t) << "self-hit at t = " << h.t;
    }
    ++tested;
  }
  EXPECT_GT(tested, 500);
}

TEST(Bvh, EmptyMeshMissesEveryRay) {
  const sl::render::Bvh bvh{sl::render::Mesh{}};
  EXPECT_TRUE(bvh.empty());
  EXPECT_TRUE(bvh.bounds().empty());
  for (const auto& r : random_rays(sl::render::Bounds3{{-1, -1, -1}, {1, 1, 1}}, 100, 1)) {
    EXPECT_FALSE(bvh.intersect(r).hit());
    EXPECT_FALSE(bvh.occluded(r));
  }
}

TEST(Bvh, InvalidRaysMissWithoutNaN) {
  const sl::render::Mesh m = random_soup(100, 2);
  const sl::render::Bvh bvh(m);
  sl::render::Ray zero;
  zero.direction = glm::vec3(0.0f);
  sl::render::Ray nan_origin;
  nan_origin.origin = glm::vec3(std::nanf(""));
  sl::render::Ray inf_dir;
  inf_dir.direction = glm::vec3(kInf, 0, 0);
  for (const sl::render::Ray& r : {zero, nan_origin, inf_dir}) {
    const sl::render::Hit h = bvh.intersect(r);
    EXPECT_FALSE(h.hit());
    EXPECT_FALSE(bvh.occluded(r));
  }
}

TEST(Bvh, AxisAlignedRaysThroughBoxFacesMatchBruteForce) {
  // A grid of unit quads: rays along axes, some starting exactly on box planes.
  sl::render::Mesh m;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      const uint32_t b = static_cast<uint32_t>(m.positions.size());
      m.positions.push_back({float(i), 0.0f, float(j)});
      m.positions.push_back({float(i + 1), 0.0f, float(j)});
      m.positions.push_back({float(i + 1), 0.3f * (i % 3), float(j + 1)});
      m.positions.push_back({float(i), 0.0f, float(j + 1)});
      m.triangles.push_back({b, b + 1, b + 2});
      m.triangles.push_back({b, b + 2, b + 3});
    }
  const sl::render::Bvh bvh(m);
  std::vector<sl::render::Ray> rays;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) {
      sl::render::Ray r;
      r.origin = {i * 0.5f, 2.0f, j * 0.5f};
      r.direction = {0.0f, -1.0f, 0.0f};
      rays.push_back(r);
      r.origin = {-1.0f, 0.1f * (i % 7), j * 0.5f};
      r.direction = {1.0f, 0.0f, 0.0f};
      rays.push_back(r);
    }
  expect_matches_brute_force(m, bvh, rays);
}

TEST(Bvh, ResultsAreIdenticalWithOneAndTwoThreads) {
  const sl::render::Mesh m = random_soup(5000, 8);
  const sl::render::Bvh bvh(m);
  const auto rays = random_rays(m.bounds(), 4000, 3);
  std::vector<sl::render::Hit> a(rays.size()), b(rays.size());
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  bvh.intersect(rays.data(), a.data(), rays.size());
  omp_set_num_threads(2);
  bvh.intersect(rays.data(), b.data(), rays.size());
  omp_set_num_threads(threads);
  for (size_t i = 0; i < rays.size(); ++i) {
    EXPECT_EQ(a[i].triangle, b[i].triangle);
    EXPECT_EQ(a[i].t, b[i].t);
  }
}

TEST(Bvh, NodesAreCompactAndLeavesSmall) {
  const sl::render::Mesh m = random_soup(20000, 12);
  const sl::render::Bvh bvh(m);
  size_t leaf_tris = 0, children = 0, interior_refs = 0;
  for (const auto& n : bvh.nodes()) {
    for (int i = 0; i < sl::render::BvhNode::kWidth; ++i) {
      const uint32_t ref = n.child[i];
      if (ref == sl::render::BvhNode::kEmpty) {
        EXPECT_GT(n.bounds[0][i], n.bounds[3][i]);  // an unused slot's box is empty
        continue;
      }
      ++children;
      if (sl::render::BvhNode::is_leaf(ref)) {
        EXPECT_LE(sl::render::BvhNode::leaf_count(ref), static_cast<uint32_t>(sl::render::Bvh::kMaxLeafSize));
        leaf_tris += sl::render::BvhNode::leaf_count(ref);
      } else {
        EXPECT_LT(ref, bvh.node_count());
        ++interior_refs;
      }
    }
  }
  EXPECT_EQ(leaf_tris, bvh.reference_count());  // pre-split triangles have more than one slot
  EXPECT_GE(bvh.reference_count(), bvh.triangle_count());
  EXPECT_EQ(interior_refs, bvh.node_count() - 1);  // every node but the root has one parent
  EXPECT_GT(children, 4 * bvh.node_count());  // wide nodes are mostly full
  EXPECT_LE(bvh.depth(), 64);
}

// Leaves share triangle blocks (bvh_build.cpp, BvhLayout::leaf): every triangle has one slot,
// no two leaves overlap, a leaf of at most 8 triangles never crosses a block boundary, and the
// blocks are fuller than one block per leaf would make them (a random soup: at least 80% of the
// lanes hold triangles, where blocks of their own leave about a third empty).
TEST(Bvh, LeavesShareBlocksWithoutOverlap) {
  const sl::render::Mesh m = random_soup(20000, 12);
  const sl::render::Bvh bvh(m);
  constexpr uint32_t kB = sl::render::Bvh::kBlockWidth;
  std::vector<std::pair<uint32_t, uint32_t>> ranges;  // [first slot, end slot) per leaf
  size_t own_blocks = 0;
  for (const auto& n : bvh.nodes())
    for (int i = 0; i < sl::render::BvhNode::kWidth; ++i) {
      const uint32_t ref = n.child[i];
      if (ref == sl::render::BvhNode::kEmpty || !sl::render::BvhNode::is_leaf(ref)) continue;
      const uint32_t first = sl::render::BvhNode::leaf_block(ref) * kB + sl::render::BvhNode::leaf_lane(ref);
      const uint32_t count = sl::render::BvhNode::leaf_count(ref);
      if (count <= kB) {
        EXPECT_EQ(first / kB, (first + count - 1) / kB) << "a small leaf crosses a block boundary";
      } else {
        EXPECT_EQ(first % kB, 0u) << "a large leaf starts mid-block";
      }
      ranges.emplace_back(first, first + count);
      own_blocks += (count + kB - 1) / kB;
    }
  std::sort(ranges.begin(), ranges.end());
  for (size_t i = 1; i < ranges.size(); ++i) ASSERT_LE(ranges[i - 1].second, ranges[i].first) << "leaves overlap";
  const size_t blocks = (ranges.back().second + kB - 1) / kB;
  EXPECT_LT(blocks, own_blocks);
  EXPECT_GE(static_cast<double>(bvh.reference_count()) / static_cast<double>(blocks * kB), 0.8);
}

TEST(Bvh, TreeDoesNotDependOnThreadCount) {
  const sl::render::Mesh m = random_soup(30000, 5);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const sl::render::Bvh one(m);
  omp_set_num_threads(2);
  const sl::render::Bvh two(m);
  omp_set_num_threads(threads);
  ASSERT_EQ(one.node_count(), two.node_count());
  for (size_t i = 0; i < one.node_count(); ++i) {
    for (int c = 0; c < sl::render::BvhNode::kWidth; ++c) {
      EXPECT_EQ(one.nodes()[i].child[c], two.nodes()[i].child[c]);
      for (int a = 0; a < 6; ++a) EXPECT_EQ(one.nodes()[i].bounds[a][c], two.nodes()[i].bounds[a][c]);
    }
  }
}

TEST(Bvh, RealModelsMatchBruteForce) {
  const std::string dir = std::string(STREETLIGHT_SHARED_DATA) + "/models";
  if (!std::filesystem::exists(dir + "/CesiumMilkTruck.glb")) GTEST_SKIP() << "shared models not found in " << dir;
  for (const char* name : {"CesiumMilkTruck.glb", "Shadow_Tester_4.glb"}) {
    const sl::render::Mesh m = sl::render::load_gltf(dir + "/" + name);
    const sl::render::Bvh bvh(m);
    SCOPED_TRACE(name);
    expect_matches_brute_force(m, bvh, random_rays(m.bounds(), 600, 17));
  }
}

}  // namespace

}  // namespace sl::test
