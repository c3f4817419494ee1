// The markdown tables of streetlight-eval's results (tools/eval.cpp writes results.json; these
// render it): Tables 1-2 per data set, one row per checkpoint, the oracle-lighting and
// constant-baseline rows, insertion PSNR by part of the region, the sky-autoencoder table, and the
// real-sky sun table split by whether the sun is inside the crop.
//
// Contract: rows are the JSON objects eval writes per checkpoint (keys as in results.json); a
// missing key prints "—"; a key with a 95% interval under "ci95" prints "v [lo, hi]".
#pragma once
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace sl::cli {

// The main table of one data set. baseline: the constant-baseline row, or null for none.
std::string eval_markdown(const std::vector<nlohmann::json>& rows, const std::vector<std::string>& names,
                          const nlohmann::json& baseline);
// The real-sky sun table (rows with a "sun" object split by crop), with the baseline row if any;
// count_title heads the count column. A row whose count is 0 prints "—" for its statistics.
std::string real_sky_markdown(const std::vector<nlohmann::json>& rows, const nlohmann::json& baseline,
                              const std::string& count_title = "crops with a hard sun");

}  // namespace sl::cli
