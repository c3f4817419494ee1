// Confidence halves (train/sun_confidence.h): the smaller spreads form the confident half, each
// half's median carries an interval that contains it, an unmeasured spread gives no split, and
// pooled medians resample whole groups.
#include "train/sun_confidence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "util/error.h"

namespace sl::test {
namespace {

TEST(SunConfidence, TheSmallerSpreadsFormTheConfidentHalf) {
  // Error grows with spread: the confident half holds the small errors.
  std::vector<double> spread, error;
  std::vector<std::string> group;
  for (int i = 0; i < 40; ++i) {
    spread.push_back(39 - i);           // reversed, so the sort matters
    error.push_back(5.0 + 2.0 * (39 - i));
    group.push_back("pano" + std::to_string(i / 4));  // four crops per panorama
  }
  const train::ConfidenceHalves h = train::confidence_halves(spread, error, group);
  ASSERT_TRUE(h.valid);
  EXPECT_EQ(h.confident.count, 20u);
  EXPECT_EQ(h.uncertain.count, 20u);
  EXPECT_DOUBLE_EQ(h.confident.median, 5.0 + 2.0 * 9.5);
  EXPECT_DOUBLE_EQ(h.uncertain.median, 5.0 + 2.0 * 29.5);
  EXPECT_DOUBLE_EQ(h.confident_spread_max, 19.0);
  EXPECT_DOUBLE_EQ(h.uncertain_spread_min, 20.0);
  for (const auto* m : {&h.confident, &h.uncertain}) {
    ASSERT_TRUE(m->ci.valid);
    EXPECT_LE(m->ci.lo, m->median);
    EXPECT_GE(m->ci.hi, m->median);
  }
  EXPECT_LT(h.confident.ci.hi, h.uncertain.ci.lo);  // well separated here
}

TEST(SunConfidence, AnUnmeasuredSpreadOrTooFewImagesGiveNoSplit) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(train::confidence_halves({1.0, nan, 3.0}, {1.0, 2.0, 3.0}, {"a", "b", "c"}).valid);
  EXPECT_FALSE(train::confidence_halves({1.0}, {1.0}, {"a"}).valid);
  EXPECT_THROW(train::confidence_halves({1.0, 2.0}, {1.0}, {"a", "b"}), Error);
  EXPECT_THROW(train::confidence_halves({1.0, 2.0}, {1.0, nan}, {"a", "b"}), Error);
}

TEST(SunConfidence, PooledMediansResampleWholeGroups) {
  // One panorama of eight identical crops and one of a single crop: resampling groups sees two
  // skies, so the interval spans both values; resampling crops would be far narrower.
  std::vector<double> v(8, 10.0);
  std::vector<std::string> g(8, "a");
  v.push_back(50.0);
  g.push_back("b");
  const train::GroupedMedian m = train::pooled_median(v, g);
  EXPECT_EQ(m.count, 9u);
  EXPECT_DOUBLE_EQ(m.median, 10.0);
  ASSERT_TRUE(m.ci.valid);
  EXPECT_DOUBLE_EQ(m.ci.lo, 10.0);
  EXPECT_DOUBLE_EQ(m.ci.hi, 50.0);
  EXPECT_EQ(train::pooled_median({}, {}).count, 0u);
}

}  // namespace
}  // namespace sl::test
