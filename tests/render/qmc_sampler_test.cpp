// Owen-scrambled Sobol pairs (render/qmc_sampler.h): the net property that makes them
// stratified, uniformity of each point, and independence between pairs and pixels.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "render/qmc_sampler.h"

namespace sl::test {

namespace {

// The first 2^m points put one point in each 2^a × 2^(m−a) elementary interval, for all a.
bool is_02_net(const std::vector<glm::vec2>& pts, int m) {
  for (int a = 0; a <= m; ++a) {
    const int nx = 1 << a, ny = 1 << (m - a);
    std::set<int> cells;
    for (const glm::vec2& p : pts) {
      if (!(p.x >= 0.0f && p.x < 1.0f && p.y >= 0.0f && p.y < 1.0f)) return false;
      cells.insert(int(p.x * nx) * ny + int(p.y * ny));
    }
    if (int(cells.size()) != (1 << m)) return false;
  }
  return true;
}

TEST(QmcSampler, UnscrambledSobolPairIsA02Net) {
  for (int m : {4, 8, 10}) {
    std::vector<glm::vec2> pts;
    for (uint32_t i = 0; i < (1u << m); ++i) {
      const sl::render::qmc::Pair32 p = sl::render::qmc::sobol_pair(i);
      pts.push_back({sl::render::qmc::to_unit(p.x), sl::render::qmc::to_unit(p.y)});
    }
    EXPECT_TRUE(is_02_net(pts, m)) << m;
  }
}

TEST(QmcSampler, ScrambledPrefixesOfEveryPairStayStratified) {
  for (uint64_t pixel : {0ull, 17ull, 123456ull})
    for (uint32_t pair : {0u, 1u, 7u, 40u})
      for (int m : {2, 5, 8}) {
        std::vector<glm::vec2> pts;
        for (uint64_t s = 0; s < (1u << m); ++s) pts.push_back(sl::render::qmc::owen_pair(3, pixel, s, pair));
        EXPECT_TRUE(is_02_net(pts, m)) << pixel << " " << pair << " " << m;
      }
  // The second block of 2^m samples is stratified too (progressive rendering continues it).
  std::vector<glm::vec2> pts;
  for (uint64_t s = 64; s < 128; ++s) pts.push_back(sl::render::qmc::owen_pair(3, 5, s, 2));
  EXPECT_TRUE(is_02_net(pts, 6));
}

// Randomised over pixels, each point is uniform on [0, 1)² (the estimator stays unbiased), and
// two pairs of one path, or one pair of two seeds, are uncorrelated.
TEST(QmcSampler, PointsAreUniformAndPairsAreDecorrelated) {
  const int n = 20000;
  double mean_x = 0, mean_y = 0, cross_pairs = 0, cross_seeds = 0;
  std::vector<int> hist(10, 0);
  for (int pixel = 0; pixel < n; ++pixel) {
    const glm::vec2 a = sl::render::qmc::owen_pair(1, pixel, 3, 1), b = sl::render::qmc::owen_pair(1, pixel, 3, 2);
    const glm::vec2 c = sl::render::qmc::owen_pair(2, pixel, 3, 1);
    mean_x += a.x / n;
    mean_y += a.y / n;
    cross_pairs += (a.x - 0.5) * (b.x - 0.5) / n;
    cross_seeds += (a.x - 0.5) * (c.x - 0.5) / n;
    ++hist[int(a.y * 10)];
  }
  // Standard error of a uniform mean: sqrt(1/12/n) ≈ 0.002; of the covariance: 1/12/sqrt(n) ≈ 0.0006.
  EXPECT_NEAR(mean_x, 0.5, 0.01);
  EXPECT_NEAR(mean_y, 0.5, 0.01);
  EXPECT_NEAR(cross_pairs, 0.0, 0.003);
  EXPECT_NEAR(cross_seeds, 0.0, 0.003);
  for (int h : hist) EXPECT_NEAR(h, n / 10, 0.1 * n / 10);
}

}  // namespace

}  // namespace sl::test
