#include "tools/common/eval_baselines.h"

#include <algorithm>
#include <memory>

#include "data/street_dataset.h"
#include "tools/common/eval_sun_stats.h"
#include "train/metrics.h"
#include "train/street_batch.h"
#include "util/error.h"

namespace sl::cli {

using data::StreetDataset;
using nlohmann::json;
using train::angular_error_deg;
using train::canonical_frame;
using train::mean_of;
using train::median;
using train::Statistic;

StreetBaseline street_baseline(const std::string& dir) {
  StreetBaseline b;
  b.from = dir;
  std::unique_ptr<StreetDataset> ds;
  try {
    ds = std::make_unique<StreetDataset>(dir, "train");
  } catch (const Error&) {
    return b;  // no train split: no baseline row
  }
  glm::dvec3 sum(0.0);
  for (size_t i = 0; i < ds->size(); ++i) {
    const data::SunLabel l = ds->load_sun_label(i);
    if (!l.sun_known) continue;
    sum += canonical_frame(l.camera).direction(l.sun_direction);
    ++b.samples;
  }
  if (b.samples == 0 || glm::length(sum) < 1e-12) return b;
  b.direction = glm::normalize(sum);
  b.has = true;
  return b;
}

json street_baseline_json(const StreetBaseline& b, const std::string& data, const std::string& split, int64_t limit) {
  const StreetDataset ds(data, split);
  const size_t count = limit > 0 ? std::min<size_t>(ds.size(), static_cast<size_t>(limit)) : ds.size();
  Grouped e;
  for (size_t i = 0; i < count; ++i) {
    const data::SunLabel l = ds.load_sun_label(i);
    if (l.sun_known) e.add(angular_error_deg(b.direction, canonical_frame(l.camera).direction(l.sun_direction)), ds.ids()[i]);
  }
  return {{"name", "constant baseline (mean training sun)"}, {"direction", {b.direction.x, b.direction.y, b.direction.z}},
          {"from", b.from}, {"from_samples", b.samples}, {"sun_error_median_deg", median(e.v)},
          {"sun_error_mean_deg", mean_of(e.v)},
          {"ci95", {{"sun_error_median_deg", ci_json(e.v, e.g, Statistic::Median)},
                    {"sun_error_mean_deg", ci_json(e.v, e.g, Statistic::Mean)}}},
          {"sun", sun_stats_json(e, {}, {}, false)}};
}

json real_sky_baseline_json(const train::RealSkyFolder& r) {
  Grouped all, in, out;
  LdrSunSplits ldr;
  for (const auto& c : r.test) {
    if (!c.sun_known) continue;
    const double e = angular_error_deg(r.baseline, c.sun_canonical);
    all.add(e, c.panorama);
    (c.sun_in_crop ? in : out).add(e, c.panorama);
    if (r.ldr) ldr.add(c, e);
  }
  json j = {{"name", "constant baseline (mean training sun)"}, {"direction", {r.baseline.x, r.baseline.y, r.baseline.z}},
            {"from_panoramas", r.baseline_from}, {"sun_error_median_deg", median(all.v)},
            {"sun_error_mean_deg", mean_of(all.v)},
            {"ci95", {{"sun_error_median_deg", ci_json(all.v, all.g, Statistic::Median)},
                      {"sun_error_mean_deg", ci_json(all.v, all.g, Statistic::Mean)}}},
            {"sun", sun_stats_json(all, in, out, true)}};
  if (r.ldr) ldr.write(j);
  return j;
}

}  // namespace sl::cli
