// Bootstrap confidence intervals for the evaluation tables (issue 13: every metric of the Table 1/2
// reproduction carries a 95% interval, so that two rows can be told apart or not).
//
// - bootstrap_ci95(values, groups, statistic): the percentile bootstrap. Each of `resamples`
//   rounds draws G groups with replacement from the G distinct groups of `values` and evaluates
//   the statistic on every value of the drawn groups; the interval is the 2.5th and 97.5th
//   percentile of the rounds (linear interpolation between order statistics).
// - Groups are clusters of values that are not independent (the crops of one real panorama share
//   its sky): resampling whole groups keeps their correlation, so the interval is not made
//   narrower by counting one sky eight times. Empty `groups`: every value is its own group.
// - Deterministic: a pure function of (values, groups, statistic, resamples, seed), draws from
//   util/random.h's counter-based generator.
// - valid = false (and lo = hi = 0) when there are no values. A single group gives lo = hi = the
//   statistic of all values.
// Throws: sl::Error when groups is non-empty and its size differs from values', when resamples < 1,
// or when a value is not finite.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace sl::train {

enum class Statistic { Median, Mean };

struct Interval {
  double lo = 0.0, hi = 0.0;
  bool valid = false;
};

Interval bootstrap_ci95(const std::vector<double>& values, const std::vector<std::string>& groups, Statistic statistic,
                        int resamples = 2000, uint64_t seed = 0x626f6f74ULL);

}  // namespace sl::train
