#include "train/bootstrap.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "train/metrics.h"
#include "util/error.h"
#include "util/random.h"

namespace sl::train {

namespace {

// The p-quantile of sorted values, interpolating linearly between order statistics.
double quantile_sorted(const std::vector<double>& s, double p) {
  const double pos = p * static_cast<double>(s.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(pos));
  const size_t j = std::min(i + 1, s.size() - 1);
  return s[i] + (pos - static_cast<double>(i)) * (s[j] - s[i]);
}

double evaluate(const std::vector<double>& v, Statistic statistic) {
  return statistic == Statistic::Median ? median(v) : mean_of(v);
}

}  // namespace

Interval bootstrap_ci95(const std::vector<double>& values, const std::vector<std::string>& groups, Statistic statistic,
                        int resamples, uint64_t seed) {
  SL_CHECK(groups.empty() || groups.size() == values.size(), "bootstrap_ci95: ", groups.size(), " group labels for ",
           values.size(), " values");
  SL_CHECK(resamples >= 1, "bootstrap_ci95: resamples must be at least 1, got ", resamples);
  for (double v : values) SL_CHECK(std::isfinite(v), "bootstrap_ci95: a value is not finite (", v, ")");
  Interval r;
  if (values.empty()) return r;
  // Clusters in first-appearance order, so the result does not depend on how labels sort.
  std::vector<std::vector<double>> clusters;
  if (groups.empty()) {
    for (double v : values) clusters.push_back({v});
  } else {
    std::map<std::string, size_t> index;
    for (size_t i = 0; i < values.size(); ++i) {
      const auto [it, added] = index.emplace(groups[i], clusters.size());
      if (added) clusters.emplace_back();
      clusters[it->second].push_back(values[i]);
    }
  }
  const int64_t g = static_cast<int64_t>(clusters.size());
  std::vector<double> stats(static_cast<size_t>(resamples)), drawn;
  drawn.reserve(values.size() * 2);
  for (int b = 0; b < resamples; ++b) {
    Rng rng(seed, static_cast<uint64_t>(b));
    drawn.clear();
    for (int64_t k = 0; k < g; ++k) {
      const auto& c = clusters[static_cast<size_t>(rng.randint(g))];
      drawn.insert(drawn.end(), c.begin(), c.end());
    }
    stats[static_cast<size_t>(b)] = evaluate(drawn, statistic);
  }
  std::sort(stats.begin(), stats.end());
  r.lo = quantile_sorted(stats, 0.025);
  r.hi = quantile_sorted(stats, 0.975);
  r.valid = true;
  return r;
}

}  // namespace sl::train
