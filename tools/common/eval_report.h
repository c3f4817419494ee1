// The markdown tables of streetlight-eval's results (tools/eval.cpp writes results.json; these
// render it): Tables 1-2 per data set, one row per checkpoint, the oracle-lighting and
// constant-baseline rows, insertion PSNR by part of the region, the sky-autoencoder table, and the
// real-sky sun table split by whether the sun is inside the crop, the confidence halves and the
// pooled sun-in-crop table.
//
// Contract: rows are the JSON objects eval writes per checkpoint (keys as in results.json); a
// missing key prints "—"; a key with a 95% interval under "ci95" prints "v [lo, hi]".
#pragma once
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "train/real_sky_benchmark.h"

namespace sl::cli {

// The main table of one data set. baseline: the constant-baseline row, or null for none.
std::string eval_markdown(const std::vector<nlohmann::json>& rows, const std::vector<std::string>& names,
                          const nlohmann::json& baseline);
// The real-sky sun table (rows with a "sun" object split by crop), with the baseline row if any;
// count_title heads the count column. A row whose count is 0 prints "—" for its statistics.
std::string real_sky_markdown(const std::vector<nlohmann::json>& rows, const nlohmann::json& baseline,
                              const std::string& count_title = "crops with a hard sun");
// The sun error in parts (eval's "sun_parts", train/sun_error_parts.h): per row, the median
// azimuth error, the median elevation bias with the true and predicted median elevations, and how
// often the predicted sun is in the other half (front/back) than the true one; "" when no row has it.
std::string sun_parts_markdown(const std::vector<nlohmann::json>& rows);
// The confidence lines (flip spread, hedge, crop spread, the sun head's probability, and that
// probability per LDR scene): per row, the median sun error of the most confident half against
// the rest, from the row's sun_confidence* objects; "" when none.
std::string confidence_markdown(const std::vector<nlohmann::json>& rows);
// The sun-in-crop table pooled over the real data sets: pooled holds {name, count,
// sun_error_median_deg, ci95} per checkpoint; the data sets whose kind is not "street" are named.
std::string pooled_markdown(const nlohmann::json& pooled, const nlohmann::json& datasets);
// The LDR panoramas' sun tables: all labelled crops, then street and other scenes and the
// low-confidence labels, each with the baseline row; then the panoramas that were not scored.
std::string ldr_markdown(const std::vector<nlohmann::json>& rows, const nlohmann::json& baseline,
                         const train::RealSkyFolder& folder);

}  // namespace sl::cli
