// The batch closest-hit query against the one-ray query, bit for bit (kept from the two-ray
// interleaved traversal tried on branch bvh-interleave, which lost and was reverted: any batch
// traversal must give exactly intersect(ray) for every ray).
#include <gtest/gtest.h>
#include <omp.h>

#include <cstring>
#include <filesystem>
#include <string>

#include "render/bvh.h"
#include "render/gltf_loader.h"
#include "support/bvh_fixtures.h"
#include "util/random.h"

namespace sl::test {
namespace {

bool same_bits(const sl::render::Hit& a, const sl::render::Hit& b) {
  return a.triangle == b.triangle && std::memcmp(&a.t, &b.t, sizeof(float)) == 0 &&
         std::memcmp(&a.u, &b.u, sizeof(float)) == 0 && std::memcmp(&a.v, &b.v, sizeof(float)) == 0;
}

// Rays of every kind the single query handles: random, short segments, tmin < 0, invalid ones.
std::vector<sl::render::Ray> mixed_rays(const sl::render::Bounds3& b, int count, uint64_t seed) {
  std::vector<sl::render::Ray> rays = random_rays(b, count, seed);
  sl::Rng rng(seed + 1);
  for (size_t i = 0; i < rays.size(); ++i) {
    if (i % 5 == 1) {
      rays[i].tmin = static_cast<float>(rng.uniform(0.0, 0.3));
      rays[i].tmax = rays[i].tmin + static_cast<float>(rng.uniform(0.0, 1.0));
    }
    if (i % 7 == 2) rays[i].tmin = -kInf;
    if (i % 37 == 3) rays[i].direction = glm::vec3(0.0f);                                    // invalid
    if (i % 41 == 4) rays[i].origin.x = std::numeric_limits<float>::quiet_NaN();              // invalid
    if (i % 43 == 5) rays[i].direction = glm::vec3(0.0f, 0.0f, rng.uniform() < 0.5 ? 1.0f : -1.0f);  // zero components
  }
  return rays;
}

// Batch vs one ray at a time over prefixes of odd and edge-case lengths, with both kernel kinds
// and with and without prefetch, on one and two threads. Returns how many rays of the whole
// batch hit (of the last configuration).
int expect_batch_matches_single(const sl::render::Mesh& m, const std::vector<sl::render::Ray>& rays) {
  const int threads = omp_get_max_threads();
  int hit_count = 0;
  for (const bool portable : {false, true})
    for (const bool prefetch : {false, true}) {
      sl::render::Bvh bvh(m);
      bvh.use_portable_kernels(portable), bvh.use_prefetch(prefetch);
      std::vector<sl::render::Hit> single(rays.size());
      for (size_t i = 0; i < rays.size(); ++i) single[i] = bvh.intersect(rays[i]);
      for (const size_t count : {size_t{0}, size_t{1}, size_t{2}, size_t{3}, size_t{63}, size_t{65}, size_t{129},
                                 rays.size() - 1, rays.size()})
        for (const int t : {1, 2}) {
          SCOPED_TRACE(testing::Message() << "portable " << portable << ", prefetch " << prefetch << ", count "
                                          << count << ", threads " << t);
          std::vector<sl::render::Hit> batch(count + 1);
          batch[count].t = 12345.0f;  // a sentinel past the end: must stay untouched
          omp_set_num_threads(t);
          bvh.intersect(rays.data(), batch.data(), count);
          omp_set_num_threads(threads);
          EXPECT_EQ(batch[count].t, 12345.0f);
          hit_count = 0;
          for (size_t i = 0; i < count; ++i) {
            if (!same_bits(batch[i], single[i])) {
              ADD_FAILURE() << "ray " << i << ": triangle " << batch[i].triangle << " / " << single[i].triangle
                            << ", t " << batch[i].t << " / " << single[i].t;
              return -1;
            }
            hit_count += single[i].hit();
          }
        }
    }
  return hit_count;
}

TEST(BvhBatch, InterleavedClosestHitIsBitIdenticalToOneRayAtATimeOnRandomSoups) {
  for (const uint64_t seed : {3u, 4u}) {
    const sl::render::Mesh m = random_soup(seed == 3 ? 5000 : 1500, seed);
    const auto rays = mixed_rays(m.bounds(), 1001, seed + 100);
    const int hits = expect_batch_matches_single(m, rays);
    EXPECT_GT(hits, seed == 3 ? 100 : 30);
    EXPECT_LT(hits, 1001);
  }
}

TEST(BvhBatch, InterleavedClosestHitIsBitIdenticalOnEqualDistanceCopies) {
  // Copies of one triangle hit at the same t: the copy reported depends on visit order.
  sl::render::Mesh m;
  m.positions = {{-1.0f, -0.5f, -1.0f}, {1.0f, -0.5f, -1.0f}, {0.0f, 0.5f, 1.0f}};
  m.triangles.assign(200, glm::uvec3(0, 1, 2));
  std::vector<sl::render::Ray> rays = mixed_rays(m.bounds(), 501, 9);
  sl::Rng rng(10);
  for (size_t i = 0; i < rays.size(); i += 2) {  // every other ray aimed at a point of the triangle
    float u = static_cast<float>(rng.uniform(0.05, 0.95)), v = static_cast<float>(rng.uniform(0.05, 0.95));
    if (u + v > 1.0f) u = 1.0f - u, v = 1.0f - v;
    const glm::vec3 target = (1.0f - u - v) * m.positions[0] + u * m.positions[1] + v * m.positions[2];
    rays[i].direction = target - rays[i].origin;
  }
  EXPECT_GT(expect_batch_matches_single(m, rays), 200);
}

TEST(BvhBatch, InterleavedClosestHitIsBitIdenticalOnARealModel) {
  const std::string path = std::string(STREETLIGHT_SHARED_DATA) + "/models/CesiumMilkTruck.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not found";
  const sl::render::Mesh m = sl::render::load_gltf(path);
  EXPECT_GT(expect_batch_matches_single(m, mixed_rays(m.bounds(), 2001, 21)), 200);
}

TEST(BvhBatch, EmptyBvhMissesEveryRayInABatch) {
  const sl::render::Bvh bvh;
  const auto rays = random_rays(sl::render::Bounds3{glm::vec3(-1.0f), glm::vec3(1.0f)}, 5, 1);
  std::vector<sl::render::Hit> hits(rays.size());
  hits[0].triangle = 7;
  bvh.intersect(rays.data(), hits.data(), rays.size());
  for (const auto& h : hits) EXPECT_FALSE(h.hit());
}

}  // namespace
}  // namespace sl::test
