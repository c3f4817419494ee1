#include "tools/common/eval_sun_stats.h"

#include <cmath>

#include "train/sun_confidence.h"

namespace sl::cli {

using nlohmann::json;
using train::Interval;
using train::Statistic;

json not_scored_json(const data::PanoramaSunLabel& l) {
  return {{"file", l.file}, {"sun", data::to_string(l.sun)}, {"confidence", data::to_string(l.confidence)},
          {"scene", data::to_string(l.scene)}};
}

json ci_json(const std::vector<double>& v, const std::vector<std::string>& groups, Statistic statistic) {
  const Interval i = train::bootstrap_ci95(v, groups, statistic);
  return i.valid ? json::array({i.lo, i.hi}) : json();
}

json interval_json(const Interval& ci) { return ci.valid ? json{ci.lo, ci.hi} : json(); }

json stats_json(const Grouped& e) {
  const train::SunErrorStats s = train::sun_error_stats(e.v);
  return {{"count", s.count}, {"median_deg", s.median_deg}, {"mean_deg", s.mean_deg},
          {"ci95", {{"median_deg", ci_json(e.v, e.g, Statistic::Median)}, {"mean_deg", ci_json(e.v, e.g, Statistic::Mean)}}},
          {"within_15", s.within_15}, {"within_30", s.within_30}, {"within_45", s.within_45}};
}

json sun_stats_json(const Grouped& all, const Grouped& in, const Grouped& out, bool split_by_crop) {
  json j = {{"all", stats_json(all)}};
  if (split_by_crop) j["sun_in_crop"] = stats_json(in), j["sun_outside_crop"] = stats_json(out);
  return j;
}

void SunSplit::add(double e, const std::string& group, bool in_crop) {
  all.add(e, group);
  (in_crop ? in : out).add(e, group);
}

json SunSplit::to_json() const { return sun_stats_json(all, in, out, true); }

void LdrSunSplits::add(const train::RealSkyCrop& c, double e, double doubt) {
  scene[c.scene].add(e, c.panorama, c.sun_in_crop);
  scene_doubt.try_emplace(c.scene, "sun_doubt").first->second.add(doubt, e, c.panorama);
  if (c.label_confidence == "low") low_confidence.add(e, c.panorama, c.sun_in_crop);
}

void LdrSunSplits::write(json& j) const {
  json s = json::object();
  for (const char* k : {"street", "other"}) {
    const auto it = scene.find(k);
    s[k] = it == scene.end() ? SunSplit().to_json() : it->second.to_json();
  }
  j["sun_by_scene"] = s;
  json d = json::object();
  for (const char* k : {"street", "other"}) {
    const auto it = scene_doubt.find(k);
    d[k] = it == scene_doubt.end() ? json() : it->second.to_json();
  }
  j["sun_confidence_probability_by_scene"] = d;
  j["sun_low_confidence"] = low_confidence.to_json();
}

json Confidence::to_json() const {
  const train::ConfidenceHalves h = train::confidence_halves(value, error, group);
  if (!h.valid) return json();
  return {{"measure", measure}, {"measure_median", h.spread_median},
          {"confident_half", {{"count", h.confident.count}, {"sun_error_median_deg", h.confident.median},
                              {"ci95", interval_json(h.confident.ci)}, {"measure_max", h.confident_spread_max}}},
          {"uncertain_half", {{"count", h.uncertain.count}, {"sun_error_median_deg", h.uncertain.median},
                              {"ci95", interval_json(h.uncertain.ci)}, {"measure_min", h.uncertain_spread_min}}}};
}

json sun_parts_json(const train::SunErrorParts& p) {
  const auto num = [](double v) { return std::isfinite(v) ? json(v) : json(); };
  return {{"count", p.count},
          {"azimuth_count", p.azimuth_count},
          {"azimuth_error_median_deg", num(p.azimuth_error_median_deg)},
          {"elevation_bias_median_deg", num(p.elevation_bias_median_deg)},
          {"true_elevation_median_deg", num(p.true_elevation_median_deg)},
          {"predicted_elevation_median_deg", num(p.predicted_elevation_median_deg)},
          {"truth_front", p.truth_front},
          {"truth_front_predicted_back", p.truth_front_predicted_back},
          {"truth_back", p.truth_back},
          {"truth_back_predicted_front", p.truth_back_predicted_front}};
}

nlohmann::json pooled_sun_in_crop(const nlohmann::json& datasets, const std::vector<std::string>& names) {
  size_t real_sets = 0;
  for (const auto& d : datasets) real_sets += d["kind"] != "street";
  if (real_sets < 2) return json::array();
  json rows = json::array();
  for (const std::string& name : names) {
    std::vector<double> e;
    std::vector<std::string> g;
    bool scored = false;
    for (const auto& d : datasets) {
      if (d["kind"] == "street") continue;
      for (const auto& r : d["results"]) {
        if (r.value("name", std::string()) != name || !r.contains("sun_per_image")) continue;
        scored = true;
        for (const auto& im : r["sun_per_image"])
          if (im.value("sun_in_crop", false)) {
            const std::string id = im["id"].get<std::string>();
            e.push_back(im["sun_error_deg"].get<double>());
            g.push_back(d["data"].get<std::string>() + "/" + id.substr(0, id.find('#')));
          }
      }
    }
    if (!scored) continue;
    const sl::train::GroupedMedian m = sl::train::pooled_median(e, g);
    rows.push_back({{"name", name}, {"count", m.count}, {"sun_error_median_deg", e.empty() ? json() : json(m.median)},
                    {"ci95", interval_json(m.ci)}});
  }
  return rows;
}

}  // namespace sl::cli
