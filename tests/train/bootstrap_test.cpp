// train/bootstrap.h: the percentile bootstrap of the evaluation tables' 95% intervals.
#include "train/bootstrap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "util/error.h"
#include "util/random.h"

namespace sl::test {
namespace {

using train::bootstrap_ci95;
using train::Interval;
using train::Statistic;

std::vector<double> normal_sample(int n, uint64_t seed) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(normal01(seed, 1, static_cast<uint64_t>(i)));
  return v;
}

// The interval of a mean of n draws of N(0, 1) has the textbook width 2·1.96/√n, and over many
// independent data sets it covers the true mean about 95% of the time.
TEST(Bootstrap, MeanIntervalHasTheNormalWidthAndCoverage) {
  const int n = 400, sets = 60;
  int covered = 0;
  double width = 0;
  for (int s = 0; s < sets; ++s) {
    const Interval ci = bootstrap_ci95(normal_sample(n, 100 + s), {}, Statistic::Mean, 1000);
    ASSERT_TRUE(ci.valid);
    ASSERT_LT(ci.lo, ci.hi);
    covered += ci.lo <= 0.0 && 0.0 <= ci.hi;
    width += (ci.hi - ci.lo) / sets;
  }
  EXPECT_NEAR(width, 2 * 1.96 / std::sqrt(n), 0.1 * 2 * 1.96 / std::sqrt(n));
  EXPECT_GE(covered, 52);  // 95% of 60 is 57; 52 is more than 3 standard deviations below it
}

// The median's interval brackets the sample median and, for N(0, 1), is about √(π/2) times wider
// than the mean's.
TEST(Bootstrap, MedianIntervalBracketsTheMedianAndIsWiderThanTheMeans) {
  const std::vector<double> v = normal_sample(800, 7);
  const Interval m = bootstrap_ci95(v, {}, Statistic::Median, 2000), a = bootstrap_ci95(v, {}, Statistic::Mean, 2000);
  std::vector<double> s = v;
  std::sort(s.begin(), s.end());
  const double med = 0.5 * (s[399] + s[400]);
  EXPECT_LE(m.lo, med);
  EXPECT_GE(m.hi, med);
  const double ratio = (m.hi - m.lo) / (a.hi - a.lo);
  EXPECT_GT(ratio, 1.0);
  EXPECT_LT(ratio, 1.7);
}

// Eight identical crops of each of five skies carry five observations, not forty: resampling
// whole groups gives the interval of five values, far wider than treating the crops as independent.
TEST(Bootstrap, GroupsAreResampledWhole) {
  std::vector<double> v;
  std::vector<std::string> g;
  const double sky[5] = {10, 25, 40, 55, 80};
  for (int k = 0; k < 5; ++k)
    for (int c = 0; c < 8; ++c) v.push_back(sky[k]), g.push_back("sky" + std::to_string(k));
  const Interval grouped = bootstrap_ci95(v, g, Statistic::Mean), naive = bootstrap_ci95(v, {}, Statistic::Mean);
  std::vector<double> five(sky, sky + 5);
  const Interval five_ci = bootstrap_ci95(five, {}, Statistic::Mean);
  EXPECT_NEAR(grouped.lo, five_ci.lo, 1.5);
  EXPECT_NEAR(grouped.hi, five_ci.hi, 1.5);
  EXPECT_GT(grouped.hi - grouped.lo, 2.0 * (naive.hi - naive.lo));
}

TEST(Bootstrap, DegenerateInputs) {
  EXPECT_FALSE(bootstrap_ci95({}, {}, Statistic::Median).valid);
  const Interval c = bootstrap_ci95({3, 3, 3, 3}, {}, Statistic::Median);
  EXPECT_TRUE(c.valid);
  EXPECT_EQ(c.lo, 3.0);
  EXPECT_EQ(c.hi, 3.0);
  const Interval one = bootstrap_ci95({1, 2, 6}, {"a", "a", "a"}, Statistic::Mean);
  EXPECT_DOUBLE_EQ(one.lo, 3.0);
  EXPECT_DOUBLE_EQ(one.hi, 3.0);
  EXPECT_THROW(bootstrap_ci95({1, 2}, {"a"}, Statistic::Mean), Error);
  EXPECT_THROW(bootstrap_ci95({1, NAN}, {}, Statistic::Mean), Error);
  EXPECT_THROW(bootstrap_ci95({1, 2}, {}, Statistic::Mean, 0), Error);
}

TEST(Bootstrap, IsAPureFunctionOfItsInputsAndSeed) {
  const std::vector<double> v = normal_sample(50, 3);
  const Interval a = bootstrap_ci95(v, {}, Statistic::Median), b = bootstrap_ci95(v, {}, Statistic::Median);
  EXPECT_EQ(a.lo, b.lo);
  EXPECT_EQ(a.hi, b.hi);
  // The median's interval ends on order statistics, so another seed may land on the same ones;
  // the mean's does not.
  const Interval m = bootstrap_ci95(v, {}, Statistic::Mean), n = bootstrap_ci95(v, {}, Statistic::Mean, 2000, 99);
  EXPECT_TRUE(m.lo != n.lo || m.hi != n.hi);
}

}  // namespace
}  // namespace sl::test
