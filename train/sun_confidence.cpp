// Confidence halves and pooled medians with grouped intervals. See sun_confidence.h.
#include "train/sun_confidence.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "train/metrics.h"
#include "util/error.h"

namespace sl::train {

GroupedMedian pooled_median(const std::vector<double>& values, const std::vector<std::string>& group) {
  SL_CHECK(group.size() == values.size(), "pooled_median: ", values.size(), " values but ", group.size(), " groups");
  GroupedMedian m;
  m.count = values.size();
  if (values.empty()) return m;
  m.median = median(values);
  m.ci = bootstrap_ci95(values, group, Statistic::Median);
  return m;
}

ConfidenceHalves confidence_halves(const std::vector<double>& spread, const std::vector<double>& error,
                                   const std::vector<std::string>& group) {
  SL_CHECK(spread.size() == error.size() && group.size() == error.size(), "confidence_halves: ", spread.size(),
           " spreads, ", error.size(), " errors and ", group.size(), " groups");
  for (double e : error) SL_CHECK(std::isfinite(e), "confidence_halves: a sun error is not finite (", e, ")");
  ConfidenceHalves h;
  if (error.size() < 2 || !std::all_of(spread.begin(), spread.end(), [](double s) { return std::isfinite(s); }))
    return h;
  std::vector<size_t> order(error.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return spread[a] < spread[b]; });
  const size_t half = order.size() / 2;
  std::vector<double> e_conf, e_unc;
  std::vector<std::string> g_conf, g_unc;
  for (size_t k = 0; k < order.size(); ++k) {
    const size_t i = order[k];
    (k < half ? e_conf : e_unc).push_back(error[i]);
    (k < half ? g_conf : g_unc).push_back(group[i]);
  }
  h.valid = true;
  h.spread_median = median(spread);
  h.confident = pooled_median(e_conf, g_conf);
  h.uncertain = pooled_median(e_unc, g_unc);
  h.confident_spread_max = spread[order[half - 1]];
  h.uncertain_spread_min = spread[order[half]];
  return h;
}

}  // namespace sl::train
