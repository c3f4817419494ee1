// The choice of rays for the radiance cache's exact corrections (render/exact_correction.h):
// unbiased for any per-ray difference, every ray once when M ≥ n, uniform without scores.
#include "render/exact_correction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace sl::test {
namespace {
using render::insertion::CorrectionPick;
using render::insertion::pick_corrections;

// The mean over u of (1/M)·Σ_j d_{k_j}/p_{k_j} (weight = 1/(M·p)) is Σ_k d_k: with u on a
// fine midpoint grid, each ray's share of u is exactly its probability up to the grid's step.
TEST(ExactCorrectionPicks, TheWeightedPicksAverageToTheFullSum) {
  const std::vector<float> score = {0.0f, 3.0f, 0.5f, 10.0f, 1.0f, 0.0f, 2.0f, 7.5f};
  const std::vector<double> d = {0.3, -1.2, 2.0, 0.7, -0.4, 5.0, 0.9, -2.2};  // any differences
  double want = 0;
  for (double v : d) want += v;
  const int n = int(score.size());
  for (int M : {1, 2, 3, 5}) {
    const int grid = 200000;
    double mean = 0;
    std::vector<CorrectionPick> picks(static_cast<size_t>(M), CorrectionPick{});
    for (int s = 0; s < grid; ++s) {
      const float u = float((s + 0.5) / grid);
      ASSERT_EQ(pick_corrections(score.data(), n, M, u, picks.data()), M);
      for (const CorrectionPick& p : picks) {
        ASSERT_GE(p.index, 0);
        ASSERT_LT(p.index, n);
        ASSERT_GT(p.weight, 0.0f);
        mean += p.weight * d[size_t(p.index)];
      }
    }
    EXPECT_NEAR(mean / grid, want, 1e-3 * std::abs(want) + 1e-3) << "M = " << M;
  }
}

TEST(ExactCorrectionPicks, EveryRayOnceWhenMReachesNAndUniformWithoutScores) {
  const std::vector<float> score = {1.0f, 2.0f, 3.0f, 4.0f};
  std::vector<CorrectionPick> picks(8);
  ASSERT_EQ(pick_corrections(score.data(), 4, 6, 0.3f, picks.data()), 4);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(picks[size_t(k)].index, k);
    EXPECT_EQ(picks[size_t(k)].weight, 1.0f);
  }
  const std::vector<float> none = {0.0f, -1.0f, NAN, 0.0f};  // negative and NaN count as 0
  ASSERT_EQ(pick_corrections(none.data(), 4, 2, 0.1f, picks.data()), 2);
  EXPECT_EQ(picks[0].index, 0);  // stratified at u = 0.05 and 0.55 of a uniform CDF
  EXPECT_EQ(picks[1].index, 2);
  for (int j = 0; j < 2; ++j) EXPECT_FLOAT_EQ(picks[size_t(j)].weight, 2.0f);  // n/M
}

}  // namespace
}  // namespace sl::test
