#include "tools/common/eval_report.h"

#include <cstdio>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace sl::cli {

using nlohmann::json;

namespace {

std::string fmt(const json& r, const char* key, int prec = 2) {
  if (!r.contains(key) || r.at(key).is_null()) return "—";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, r.at(key).get<double>());
  return b;
}

// "v [lo, hi]" when the row has a 95% interval for the key (train/bootstrap.h), else fmt's "v".
std::string fmt_ci(const json& r, const char* key, int prec = 2) {
  std::string v = fmt(r, key, prec);
  if (!r.contains("ci95") || !r["ci95"].contains(key) || !r["ci95"][key].is_array()) return v;
  char b[96];
  std::snprintf(b, sizeof b, " [%.*f, %.*f]", prec, r["ci95"][key][0].get<double>(), prec, r["ci95"][key][1].get<double>());
  return v + b;
}

// " [lo, hi]" of a 95% interval (a JSON pair), or "" for null.
std::string ci_text(const json& ci) {
  if (ci.is_null()) return "";
  char b[64];
  std::snprintf(b, sizeof b, " [%.1f, %.1f]", ci[0].get<double>(), ci[1].get<double>());
  return b;
}

}  // namespace

std::string eval_markdown(const std::vector<json>& rows, const std::vector<std::string>& names, const json& baseline) {
  std::ostringstream md;
  bool any_light = false, any_sky = false;
  for (const auto& r : rows) (r.contains("sky_log_l2") ? any_sky : any_light) = true;
  if (any_light) {
    md << "| checkpoint | stage (step) | sun median ° | sun mean ° | PSNR | si-PSNR | PSNR upper | si-PSNR upper | "
          "insertion PSNR | shadow-ratio err | ms/image |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (size_t i = 0; i < rows.size(); ++i) {
      const json& r = rows[i];
      if (r.contains("sky_log_l2")) continue;
      md << "| " << names[i] << " | " << r["stage"].get<std::string>() << " (" << r["step"].get<int64_t>() << ") | "
         << fmt_ci(r, "sun_error_median_deg", 1) << " | " << fmt_ci(r, "sun_error_mean_deg", 1) << " | "
         << fmt_ci(r, "psnr") << " | " << fmt_ci(r, "si_psnr") << " | " << fmt_ci(r, "psnr_upper") << " | "
         << fmt_ci(r, "si_psnr_upper") << " | " << fmt_ci(r, "insertion_psnr") << " | "
         << fmt_ci(r, "shadow_ratio_error", 3) << " | " << fmt(r, "inference_ms", 0) << " |\n";
    }
    for (const auto& r : rows)
      if (r.contains("oracle"))
        md << "| oracle lighting (the generator's HDR " << r["oracle"].value("light", "panorama at the camera")
           << ") | — | — | — | — | — | — | — | "
           << fmt_ci(r["oracle"], "insertion_psnr") << " | " << fmt_ci(r["oracle"], "shadow_ratio_error", 3) << " | — |\n";
    if (!baseline.is_null())
      md << "| " << baseline["name"].get<std::string>() << " | — | " << fmt_ci(baseline, "sun_error_median_deg", 1)
         << " | " << fmt_ci(baseline, "sun_error_mean_deg", 1) << " | — | — | — | — | — | — | — |\n";
  }
  bool any_parts = false;
  for (const auto& r : rows) any_parts = any_parts || r.contains("insertion_psnr_parts");
  if (any_parts) {
    md << "\nInsertion PSNR by part of the region (object interior, object edge, shadow):\n\n"
          "| lighting | object | edge | shadow |\n|---|---|---|---|\n";
    auto parts_row = [&](const std::string& name, const json& p) {
      md << "| " << name << " | " << fmt(p, "object") << " | " << fmt(p, "edge") << " | " << fmt(p, "shadow") << " |\n";
    };
    for (size_t i = 0; i < rows.size(); ++i)
      if (rows[i].contains("insertion_psnr_parts")) parts_row(names[i], rows[i]["insertion_psnr_parts"]);
    for (const auto& r : rows)
      if (r.contains("oracle") && r["oracle"].contains("insertion_psnr_parts"))
        parts_row("oracle lighting", r["oracle"]["insertion_psnr_parts"]);
  }
  if (any_sky) {
    md << (any_light ? "\n" : "")
       << "| checkpoint | step | sky log-L2 | sun median ° | sun mean ° | ms/image |\n|---|---|---|---|---|---|\n";
    for (size_t i = 0; i < rows.size(); ++i) {
      const json& r = rows[i];
      if (!r.contains("sky_log_l2")) continue;
      md << "| " << names[i] << " | " << r["step"].get<int64_t>() << " | " << fmt(r, "sky_log_l2", 4) << " | "
         << fmt(r, "sun_error_median_deg", 1) << " | " << fmt(r, "sun_error_mean_deg", 1) << " | "
         << fmt(r, "inference_ms", 1) << " |\n";
    }
  }
  return md.str();
}

// Table 1 on real skies: one row per lighting checkpoint and the constant baseline.
std::string real_sky_markdown(const std::vector<json>& rows, const json& baseline, const std::string& count_title) {
  std::ostringstream md;
  md << "| model | " << count_title << " | median ° [95% CI] | mean ° [95% CI] | ≤15° | ≤30° | ≤45° | "
        "sun in crop: median ° (n) | sun outside: median ° (n) |\n|---|---|---|---|---|---|---|---|---|\n";
  auto row = [&](const std::string& name, const json& sun) {
    const json& a = sun.at("all");
    if (a.at("count").get<size_t>() == 0) {  // an empty subset has no statistics
      md << "| " << name << " | 0 | — | — | — | — | — | — (0) | — (0) |\n";
      return;
    }
    char b[640];
    auto part = [](const json& p) {  // "median (n)", a dash for an empty part
      const size_t n = p.at("count").get<size_t>();
      char c[64];
      if (n == 0) return std::string("— (0)");
      const size_t cue = p.value("visible_sun_fired", size_t{0});
      if (cue > 0) std::snprintf(c, sizeof c, "%.1f (%zu, cue %zu)", p.at("median_deg").get<double>(), n, cue);
      else std::snprintf(c, sizeof c, "%.1f (%zu)", p.at("median_deg").get<double>(), n);
      return std::string(c);
    };
    std::snprintf(b, sizeof b, "| %s | %zu | %s | %s | %.2f | %.2f | %.2f | %s | %s |\n", name.c_str(),
                  a.at("count").get<size_t>(), fmt_ci(a, "median_deg", 1).c_str(), fmt_ci(a, "mean_deg", 1).c_str(),
                  a.at("within_15").get<double>(), a.at("within_30").get<double>(), a.at("within_45").get<double>(),
                  part(sun.at("sun_in_crop")).c_str(), part(sun.at("sun_outside_crop")).c_str());
    md << b;
  };
  for (const auto& r : rows)
    if (r.contains("sun") && r.at("sun").contains("sun_in_crop")) row(r.at("name").get<std::string>(), r.at("sun"));
  if (!baseline.is_null()) row(baseline.at("name").get<std::string>(), baseline.at("sun"));
  return md.str();
}

std::string sun_parts_markdown(const std::vector<json>& rows) {
  std::string md;
  for (const auto& r : rows) {
    if (!r.contains("sun_parts") || r.at("sun_parts").value("count", 0) == 0) continue;
    const json& p = r.at("sun_parts");
    char b[512];
    std::snprintf(b, sizeof b,
                  "- %s: azimuth error median %s° (%zu of %zu images, suns below 85°); elevation predicted minus true, "
                  "median %s° (true %s°, predicted %s°); in the wrong half %zu of %zu (true sun in front: %zu of %zu "
                  "put behind; behind: %zu of %zu put in front)\n",
                  r.at("name").get<std::string>().c_str(), fmt(p, "azimuth_error_median_deg", 1).c_str(),
                  p["azimuth_count"].get<size_t>(), p["count"].get<size_t>(),
                  fmt(p, "elevation_bias_median_deg", 1).c_str(), fmt(p, "true_elevation_median_deg", 1).c_str(),
                  fmt(p, "predicted_elevation_median_deg", 1).c_str(),
                  p["truth_front_predicted_back"].get<size_t>() + p["truth_back_predicted_front"].get<size_t>(),
                  p["count"].get<size_t>(), p["truth_front_predicted_back"].get<size_t>(),
                  p["truth_front"].get<size_t>(), p["truth_back_predicted_front"].get<size_t>(),
                  p["truth_back"].get<size_t>());
    md += b;
  }
  return md.empty() ? md
                    : "\nThe sun error in parts (train/sun_error_parts.h; in the input camera's frame, front = the "
                      "half the view looks into):\n\n" + md;
}

std::string confidence_markdown(const std::vector<json>& results) {
  std::string md;
  const auto line = [&](const json& r, const json& c, const std::string& what, const std::string& subset = "") {
    if (c.is_null()) return;
    char b[512];
    std::snprintf(b, sizeof b,
                  "- %s, by %s: sun error median %.1f°%s on the most confident half (%zu images, ≤ %.2f) against "
                  "%.1f°%s on the rest (%zu, ≥ %.2f)\n",
                  (r.at("name").get<std::string>() + subset).c_str(), what.c_str(),
                  c["confident_half"]["sun_error_median_deg"].get<double>(),
                  ci_text(c["confident_half"]["ci95"]).c_str(), c["confident_half"]["count"].get<size_t>(),
                  c["confident_half"]["measure_max"].get<double>(),
                  c["uncertain_half"]["sun_error_median_deg"].get<double>(), ci_text(c["uncertain_half"]["ci95"]).c_str(),
                  c["uncertain_half"]["count"].get<size_t>(), c["uncertain_half"]["measure_min"].get<double>());
    md += b;
  };
  for (const auto& [key, what] : std::vector<std::pair<std::string, std::string>>{
           {"sun_confidence", "flip spread (°)"},
           {"sun_confidence_hedge", "sun height (hedge)"},
           {"sun_confidence_crop", "crop spread (°)"},
           {"sun_confidence_probability", "doubt, 1 − sun probability"}})
    for (const auto& r : results)
      if (r.contains(key)) line(r, r.at(key), what);
  for (const char* scene : {"street", "other"})
    for (const auto& r : results)
      if (r.contains("sun_confidence_probability_by_scene"))
        line(r, r.at("sun_confidence_probability_by_scene").value(scene, json()),
             "doubt, 1 − sun probability", std::string(", ") + scene + " scenes");
  return md.empty() ? md
                    : "\nConfidence (train/inference.h): the angle between the sun of the photo and of its mirror "
                      "image; the sun height sin(elevation) of the network's sun, a hedge toward the zenith when "
                      "it cannot tell the azimuth; the largest angle between the photo's sun and a centred "
                      "crop's (crop averaging) (all 0 when the visible-sun cue set the direction); and the sun "
                      "head's probability near its mode (1 when the cue set the direction):\n\n" +
                          md;
}

std::string pooled_markdown(const json& pooled, const json& datasets) {
  std::string sets;
  for (const auto& d : datasets)
    if (d["kind"] != "street") sets += (sets.empty() ? "" : ", ") + d["data"].get<std::string>();
  std::string md = "## Sun in crop, pooled over the real data sets (" + sets + ")\n\n| model | crops | median ° [95% CI] |\n|---|---|---|\n";
  for (const auto& r : pooled) {
    char b[256];
    if (r["sun_error_median_deg"].is_null())
      std::snprintf(b, sizeof b, "| %s | 0 | — |\n", r["name"].get<std::string>().c_str());
    else
      std::snprintf(b, sizeof b, "| %s | %zu | %.1f%s |\n", r["name"].get<std::string>().c_str(), r["count"].get<size_t>(),
                    r["sun_error_median_deg"].get<double>(), ci_text(r["ci95"]).c_str());
    md += b;
  }
  return md + "\n";
}

std::string ldr_markdown(const std::vector<json>& results, const json& baseline, const train::RealSkyFolder& r) {
  std::string md = "\nSun direction on real LDR panoramas (hand-labelled suns, all scenes):\n\n" +
                   real_sky_markdown(results, baseline, "labelled crops");
  auto subset = [&](const std::string& title, auto pick) {
    std::vector<json> rows;
    for (const auto& res : results)
      if (res.contains("sun_by_scene")) rows.push_back({{"name", res.at("name")}, {"sun", pick(res)}});
    json b;
    if (!baseline.is_null()) b = {{"name", baseline.at("name")}, {"sun", pick(baseline)}};
    md += "\n" + title + ":\n\n" + real_sky_markdown(rows, b, "labelled crops");
  };
  subset("Street scenes", [](const json& j) { return j.at("sun_by_scene").at("street"); });
  subset("Other scenes", [](const json& j) { return j.at("sun_by_scene").at("other"); });
  subset("Low-confidence labels (also counted above)", [](const json& j) { return j.at("sun_low_confidence"); });
  md += "\nScored panoramas: " + std::to_string(r.scored.size()) + "; not scored (no sun position): " +
        std::to_string(r.not_scored.size());
  std::string sep = " — ";
  for (const auto& n : r.not_scored) {
    md += sep + n.file + " (" + data::to_string(n.sun) + ")";
    sep = ", ";
  }
  return md + "\n";
}

}  // namespace sl::cli
