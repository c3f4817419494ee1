// tools/common/eval_sun_stats.h and eval_report.h: the LDR panoramas' confidence halves per scene
// (the sun head's doubt, 1 − sun probability) and their lines in results.md.
#include "tools/common/eval_sun_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "tools/common/eval_report.h"

namespace sl::test {
namespace {

train::RealSkyCrop crop(const std::string& panorama, const std::string& scene) {
  train::RealSkyCrop c;
  c.panorama = panorama;
  c.scene = scene;
  c.sun_known = true;
  return c;
}

// Four street crops of four panoramas and two other-scene crops: per scene, the half with the
// smaller doubt against the rest; a model without a sun head (doubt NaN) gives null halves.
TEST(EvalSunStats, LdrConfidenceHalvesPerScene) {
  cli::LdrSunSplits s;
  const double doubt[4] = {0.1, 0.9, 0.2, 0.8}, error[4] = {5, 50, 7, 70};
  for (int i = 0; i < 4; ++i) s.add(crop("s" + std::to_string(i) + ".jpg", "street"), error[i], doubt[i]);
  s.add(crop("o0.jpg", "other"), 30, 0.5);
  s.add(crop("o1.jpg", "other"), 10, 0.4);
  nlohmann::json j;
  s.write(j);
  const auto& street = j["sun_confidence_probability_by_scene"]["street"];
  ASSERT_FALSE(street.is_null()) << j.dump();
  EXPECT_EQ(street["measure"], "sun_doubt");
  EXPECT_EQ(street["confident_half"]["count"], 2);
  EXPECT_EQ(street["uncertain_half"]["count"], 2);
  EXPECT_DOUBLE_EQ(street["confident_half"]["sun_error_median_deg"].get<double>(), 6.0);
  EXPECT_DOUBLE_EQ(street["uncertain_half"]["sun_error_median_deg"].get<double>(), 60.0);
  const auto& other = j["sun_confidence_probability_by_scene"]["other"];
  ASSERT_FALSE(other.is_null());
  EXPECT_DOUBLE_EQ(other["confident_half"]["sun_error_median_deg"].get<double>(), 10.0);
  EXPECT_EQ(j["sun_by_scene"]["street"]["all"]["count"], 4);

  // The markdown names the scene's halves beside the row's name.
  nlohmann::json row = j;
  row["name"] = "model";
  const std::string md = cli::confidence_markdown({row});
  EXPECT_NE(md.find("model, street scenes, by doubt, 1 − sun probability: sun error median 6.0°"), std::string::npos)
      << md;
  EXPECT_NE(md.find("other scenes"), std::string::npos) << md;

  cli::LdrSunSplits none;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  none.add(crop("a.jpg", "street"), 10, nan);
  none.add(crop("b.jpg", "street"), 20, nan);
  nlohmann::json k;
  none.write(k);
  EXPECT_TRUE(k["sun_confidence_probability_by_scene"]["street"].is_null()) << k.dump();
  EXPECT_TRUE(k["sun_confidence_probability_by_scene"]["other"].is_null()) << k.dump();
}

}  // namespace
}  // namespace sl::test
