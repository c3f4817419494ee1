// The sun-error statistics streetlight-eval writes to results.json: errors with the group each
// belongs to (the crops of one panorama, the views of one street), their summary with 95%
// bootstrap intervals that resample whole groups (train/bootstrap.h), the real-crop splits (sun
// inside the crop or outside; LDR panoramas by scene and by label confidence), the confidence
// halves (train/sun_confidence.h) and the sun error in parts (train/sun_error_parts.h).
//
// Contract: every interval is [lo, hi], or null when there are no values; medians of nothing are
// null in sun_parts_json. The key names are those of results.json (tools/common/eval_report.h
// renders them).
#pragma once
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/sun_labels.h"
#include "train/bootstrap.h"
#include "train/real_sky_benchmark.h"
#include "train/sun_error_parts.h"

namespace sl::cli {

// The JSON of a panorama left unscored (its label has no sun position).
nlohmann::json not_scored_json(const data::PanoramaSunLabel& l);

// The 95% bootstrap interval of `statistic` over v, resampling the values of one group together.
nlohmann::json ci_json(const std::vector<double>& v, const std::vector<std::string>& groups,
                       train::Statistic statistic);
nlohmann::json interval_json(const train::Interval& ci);

// Values with their group labels.
struct Grouped {
  std::vector<double> v;
  std::vector<std::string> g;
  void add(double value, const std::string& group) { v.push_back(value), g.push_back(group); }
};

// count, median, mean (with intervals) and the shares within 15°, 30° and 45°.
nlohmann::json stats_json(const Grouped& e);
// {"all": ...}, and with split_by_crop also "sun_in_crop" and "sun_outside_crop".
nlohmann::json sun_stats_json(const Grouped& all, const Grouped& in, const Grouped& out, bool split_by_crop);

// Sun errors of real crops: all, sun inside the crop, sun outside.
struct SunSplit {
  Grouped all, in, out;
  void add(double e, const std::string& group, bool in_crop);
  nlohmann::json to_json() const;
};
// Does the network know when it is right? One confidence measure (smaller = more confident) over
// the labelled images of a result row: the median error of the most confident half against the
// rest's, each with its 95% interval resampling whole groups; null for fewer than 2 images.
struct Confidence {
  explicit Confidence(std::string m) : measure(std::move(m)) {}
  std::string measure;  // the per-image key it is read from
  std::vector<double> value, error;
  std::vector<std::string> group;
  void add(double v, double e, const std::string& g) { value.push_back(v), error.push_back(e), group.push_back(g); }
  nlohmann::json to_json() const;
};

// LDR panoramas: by the label's scene (street / other) and the low-confidence labels apart, and
// the sun head's confidence halves per scene (doubt = 1 − sun probability, NaN when the model has
// no sun head); write() adds "sun_by_scene", "sun_low_confidence" and
// "sun_confidence_probability_by_scene" (street / other, each as Confidence::to_json) to j.
struct LdrSunSplits {
  std::map<std::string, SunSplit> scene;
  std::map<std::string, Confidence> scene_doubt;
  SunSplit low_confidence;
  void add(const train::RealSkyCrop& c, double e, double doubt = std::numeric_limits<double>::quiet_NaN());
  void write(nlohmann::json& j) const;
};

nlohmann::json sun_parts_json(const train::SunErrorParts& p);

// "Sun in crop" pooled over every real data set of a run (results.json's "datasets": HDR and LDR
// panorama folders): per checkpoint name, the median error of the crops whose sun is inside the
// crop, with its interval resampling whole panoramas. Empty when fewer than two real data sets
// were scored.
nlohmann::json pooled_sun_in_crop(const nlohmann::json& datasets, const std::vector<std::string>& names);

}  // namespace sl::cli
