// streetlight-eval on a tiny generated street dataset: every metric of Sec 4.2 is reported, one
// table row per checkpoint, the error-against-time plot is written, and bad input is one line.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <algorithm>
#include <iterator>

#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sky_model.h"
#include "support/street_fixture.h"
#include "support/tiny_ldr_folder.h"
#include "support/tool_fixture.h"
#include "data/street_dataset.h"
#include "data/sun_labels.h"
#include "render/equirect.h"
#include "train/real_sky_benchmark.h"
#include "train/sun_error_parts.h"
#include "train/street_batch.h"
#include "util/math.h"

namespace sl::test {

namespace fs = std::filesystem;

TEST(EvalTool, ReportsTheMetricsOfTables1And2WithARowPerCheckpoint) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP() << "streetlight-eval not built";
  const std::string dir = sl::test::tool_dir("eval_ok");
  const std::string data = sl::test::tiny_dataset("eval_tiny_dataset", 3);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --checkpoint " + ckpt +
                                                          " --name a --name b --data " + data +
                                                          " --split train --view-rows 8 --out " + dir + "/out");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/out/results.json");
  const auto j = nlohmann::json::parse(jf);
  ASSERT_EQ(j["results"].size(), 2u);
  for (const char* k : {"sun_error_median_deg", "sun_error_mean_deg", "psnr", "si_psnr", "psnr_upper", "si_psnr_upper",
                        "inference_ms"})
    EXPECT_TRUE(j["results"][0].contains(k)) << k;
  EXPECT_GE(j["results"][0]["si_psnr"].get<double>(), j["results"][0]["psnr"].get<double>() - 1e-9);
  EXPECT_TRUE(fs::exists(dir + "/out/results.md"));
  EXPECT_TRUE(fs::exists(dir + "/out/error_time.png"));
  EXPECT_EQ(j["results"][0]["sun_error_median_deg"], j["results"][1]["sun_error_median_deg"]);  // deterministic
  EXPECT_EQ(j["results"][0]["flip_average"], true);  // the estimator's default (--no-flip-average: off)
  // Per image: one entry per labelled image, whose errors are the ones the median is taken of,
  // and each error is the angle between the two directions it lists.
  const auto& per = j["results"][0]["sun_per_image"];
  ASSERT_EQ(per.size(), j["results"][0]["images"].get<size_t>() - j["results"][0]["sun_unknown"].get<size_t>());
  ASSERT_FALSE(per.empty());
  std::vector<double> errors;
  for (const auto& e : per) {
    const glm::dvec3 p(e["predicted"][0], e["predicted"][1], e["predicted"][2]);
    const glm::dvec3 t(e["truth"][0], e["truth"][1], e["truth"][2]);
    const double angle = std::acos(std::clamp(glm::dot(glm::normalize(p), glm::normalize(t)), -1.0, 1.0)) * 180.0 / kPi;
    EXPECT_NEAR(e["sun_error_deg"].get<double>(), angle, 1e-6) << e.dump();
    EXPECT_FALSE(e["id"].get<std::string>().empty());
    errors.push_back(e["sun_error_deg"].get<double>());
  }
  std::sort(errors.begin(), errors.end());
  const size_t n = errors.size();
  const double med = n % 2 ? errors[n / 2] : 0.5 * (errors[n / 2 - 1] + errors[n / 2]);
  EXPECT_NEAR(med, j["results"][0]["sun_error_median_deg"].get<double>(), 1e-9);
  // Insertion error, also by part of the region, and the oracle row naming the light it used
  // (the tiny dataset has no light probe at the object).
  const auto& first = j["results"][0];
  ASSERT_TRUE(first.contains("insertion_psnr")) << first.dump();
  EXPECT_TRUE(first["insertion_psnr_parts"].contains("object")) << first.dump();
  ASSERT_TRUE(first.contains("oracle")) << first.dump();
  EXPECT_EQ(first["oracle"]["light"], "panorama at the camera");
  EXPECT_TRUE(first["oracle"]["insertion_psnr_parts"].contains("object"));
}

// Issue 13's table needs intervals to tell rows apart, and a constant baseline on streets too.
TEST(EvalTool, EveryMetricHasABootstrapIntervalAndStreetsHaveTheBaselineOfTheirTrainSplit) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP() << "streetlight-eval not built";
  const std::string dir = sl::test::tool_dir("eval_ci");
  const std::string data = sl::test::tiny_dataset("eval_tiny_dataset", 3);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + data +
                                                          " --split train --view-rows 8 --no-budgets --baseline-data " +
                                                          data + " --out " + dir + "/out");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/out/results.json");
  const auto j = nlohmann::json::parse(jf);
  const auto& row = j["results"][0];
  for (const char* k : {"sun_error_median_deg", "sun_error_mean_deg", "psnr", "si_psnr", "psnr_upper", "si_psnr_upper",
                        "insertion_psnr", "shadow_ratio_error"}) {
    ASSERT_TRUE(row["ci95"][k].is_array()) << k << ": " << row.dump();
    const double lo = row["ci95"][k][0].get<double>(), hi = row["ci95"][k][1].get<double>(), v = row[k].get<double>();
    EXPECT_LE(lo, hi) << k;
    if (std::string(k) != "sun_error_median_deg") {  // a mean lies inside its own interval
      EXPECT_TRUE(lo <= v + 1e-9 && v <= hi + 1e-9) << k;
    }
  }
  EXPECT_TRUE(row["oracle"]["ci95"]["insertion_psnr"].is_array());
  // The baseline: the normalised mean canonical sun of the train split, from meta.json.
  const auto& b = j["datasets"][0]["baseline"];
  const sl::data::StreetDataset ds(data, "train");
  glm::dvec3 sum(0.0);
  for (size_t i = 0; i < ds.size(); ++i) {
    const sl::data::SunLabel l = ds.load_sun_label(i);
    if (l.sun_known) sum += sl::train::canonical_frame(l.camera).direction(l.sun_direction);
  }
  const glm::dvec3 expect = glm::normalize(sum);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(b["direction"][k].get<double>(), expect[k], 1e-9);
  EXPECT_TRUE(b["ci95"]["sun_error_median_deg"].is_array());
  std::ifstream mf(dir + "/out/results.md");
  const std::string md((std::istreambuf_iterator<char>(mf)), std::istreambuf_iterator<char>());
  EXPECT_NE(md.find("constant baseline (mean training sun)"), std::string::npos) << md;
  EXPECT_NE(md.find(" ["), std::string::npos) << md;
  // A --baseline-data that is not a street dataset is one line, exit 2.
  const auto bad = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + data +
                                                            " --baseline-data " + dir + "/nothing");
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("--baseline-data"), std::string::npos) << bad.out;
}

TEST(EvalTool, MissingDataIsACleanError) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("eval_bad");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + dir + "/nothing");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
}

// The glare detector's two weights (train/inference.h set_sun_glare): a negative number, infinity or
// a word is one error line naming the option, exit 2, nothing written.
TEST(EvalTool, ABadGlareWeightIsACleanError) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("eval_azimuth_weight");
  const std::string data = sl::test::tiny_dataset("eval_tiny_dataset", 3);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  for (const char* option : {"--glare-azimuth-weight", "--glare-map-weight"})
    for (const char* bad : {"-1", "abc", "inf"}) {
      const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + data +
                                                                " --split train --no-budgets " + option + " " + bad +
                                                                " --out " + dir + "/bad");
      EXPECT_EQ(r.code, 2) << option << " " << bad << ": " << r.out;
      EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
      EXPECT_NE(r.out.find(option), std::string::npos) << r.out;
      EXPECT_FALSE(fs::exists(dir + "/bad")) << bad;
    }
}

// Crop averaging (train/inference.h set_crop_scales) from the command line: off by default, and
// with --crop-scales each labelled image carries its crop spread and the report ranks by it; a
// scale outside (0, 1) or a word is one error line naming the option, exit 2.
TEST(EvalTool, CropScalesAddTheCropSpreadAndBadScalesAreRefused) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("eval_crops");
  const std::string data = sl::test::tiny_dataset("eval_tiny_dataset", 3);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const std::string base = "--checkpoint " + ckpt + " --data " + data + " --split train --view-rows 8 --no-budgets";
  for (const char* bad : {"0.5,1.2", "0.5,x", "0"}) {
    const auto r = sl::test::run_tool("streetlight-eval", base + " --crop-scales " + bad + " --out " + dir + "/bad");
    EXPECT_EQ(r.code, 2) << bad << ": " << r.out;
    EXPECT_NE(r.out.find("--crop-scales"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir + "/bad")) << bad;
  }
  const auto r = sl::test::run_tool("streetlight-eval", base + " --crop-scales 0.6,0.8 --out " + dir + "/out");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/out/results.json");
  const auto j = nlohmann::json::parse(jf);
  const auto& res = j["results"][0];
  EXPECT_EQ(res["crop_scales"], nlohmann::json({0.6, 0.8}));
  ASSERT_FALSE(res["sun_per_image"].empty());
  for (const auto& e : res["sun_per_image"]) EXPECT_GE(e["sun_crop_spread_deg"].get<double>(), 0.0) << e.dump();
  EXPECT_TRUE(res.contains("sun_confidence_crop"));
}

namespace {

// A tiny folder of real-panorama stand-ins (clear skies with a hard sun) and a split file.
std::string tiny_panorama_folder(const std::string& dir) {
  const std::string pano_dir = dir + "/panos";
  fs::create_directories(pano_dir);
  const double suns[3][2] = {{30, 10}, {60, -100}, {20, 150}};
  const char* names[3] = {"a_1k.hdr", "b_1k.hdr", "c_1k.exr"};
  for (int i = 0; i < 3; ++i) {
    sl::data::SkyParams p;
    p.sun_elevation_rad = suns[i][0] * sl::kPi / 180;
    p.sun_azimuth_rad = suns[i][1] * sl::kPi / 180;
    sl::data::write_image(pano_dir + "/" + names[i], sl::data::PreethamSky(p).render(32, 64));
  }
  std::ofstream(dir + "/split.json") << R"({"comment": "test", "train": ["a_1k.hdr", "b_1k.hdr"], "test": ["c_1k.exr"]})";
  return pano_dir;
}

}  // namespace

TEST(EvalTool, RealSkyBenchmarkReportsTable1BesideTheBaselineOfTheTrainingSplit) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP() << "streetlight-eval not built";
  const std::string dir = sl::test::tool_dir("eval_real");
  const std::string panos = tiny_panorama_folder(dir);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --name tiny --data " + panos +
                                                          " --hdri-split " + dir + "/split.json --crops 3 --view-rows 8 --out " +
                                                          dir + "/out");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/out/results.json");
  const auto j = nlohmann::json::parse(jf);
  const auto& d = j["datasets"][0];
  EXPECT_EQ(d["kind"], "real_panoramas");
  EXPECT_EQ(d["results"][0]["images"], 3);  // 3 crops of the one test panorama
  const auto& sun = d["results"][0]["sun"];
  for (const char* k : {"all", "sun_in_crop", "sun_outside_crop"})
    for (const char* m : {"count", "median_deg", "mean_deg", "within_15", "within_30", "within_45"})
      EXPECT_TRUE(sun[k].contains(m)) << k << "." << m;
  EXPECT_EQ(sun["all"]["count"].get<int>(), sun["sun_in_crop"]["count"].get<int>() + sun["sun_outside_crop"]["count"].get<int>());
  const auto& per = d["results"][0]["sun_per_image"];
  ASSERT_EQ(per.size(), sun["all"]["count"].get<size_t>());
  std::vector<glm::dvec3> predicted, truth;
  for (const auto& e : per) {
    EXPECT_EQ(e["id"].get<std::string>().rfind("c_1k.exr#", 0), 0u) << e.dump();  // the test panorama's crops
    EXPECT_TRUE(e.contains("sun_in_crop"));
    predicted.emplace_back(e["predicted"][0].get<double>(), e["predicted"][1].get<double>(), e["predicted"][2].get<double>());
    truth.emplace_back(e["truth"][0].get<double>(), e["truth"][1].get<double>(), e["truth"][2].get<double>());
  }
  // The error in parts is train/sun_error_parts.h of the per-image suns the JSON lists.
  const auto& parts = d["results"][0]["sun_parts"];
  const sl::train::SunErrorParts expect_parts = sl::train::sun_error_parts(predicted, truth);
  EXPECT_EQ(parts["count"].get<size_t>(), per.size());
  EXPECT_EQ(parts["truth_front"].get<size_t>() + parts["truth_back"].get<size_t>(), per.size());
  EXPECT_EQ(parts["truth_front_predicted_back"].get<size_t>(), expect_parts.truth_front_predicted_back);
  EXPECT_EQ(parts["truth_back_predicted_front"].get<size_t>(), expect_parts.truth_back_predicted_front);
  EXPECT_NEAR(parts["elevation_bias_median_deg"].get<double>(), expect_parts.elevation_bias_median_deg, 1e-9);
  // The baseline comes from the training split only, computed as the library does.
  const auto& b = d["baseline"];
  EXPECT_EQ(b["from_panoramas"], nlohmann::json({"a_1k.hdr", "b_1k.hdr"}));
  const auto crops = sl::train::real_sky_crops({panos + "/a_1k.hdr", panos + "/b_1k.hdr"}, 3, 0x7265616c736b79ULL);
  const glm::dvec3 expect = sl::train::constant_baseline_direction(crops);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(b["direction"][k].get<double>(), expect[k], 1e-9);
  const auto all3 = sl::train::real_sky_crops({panos + "/a_1k.hdr", panos + "/b_1k.hdr", panos + "/c_1k.exr"}, 3,
                                              0x7265616c736b79ULL);
  EXPECT_GT(glm::length(sl::train::constant_baseline_direction(all3) - expect), 1e-6) << "the test sky changes nothing";
  std::ifstream mf(dir + "/out/results.md");
  const std::string md((std::istreambuf_iterator<char>(mf)), std::istreambuf_iterator<char>());
  EXPECT_NE(md.find("constant baseline"), std::string::npos) << md;
  EXPECT_NE(md.find("The sun error in parts"), std::string::npos) << md;
}

TEST(EvalTool, BadPanoramaInputIsOneLineNamingTheFileAndWritesNothing) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("eval_real_bad");
  const std::string panos = tiny_panorama_folder(dir);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  auto expect_error = [&](const std::string& args, const std::string& names) {
    const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " " + args + " --out " + dir + "/out");
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_NE(r.out.find(names), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir + "/out/results.json"));
  };
  // A split file that names a missing panorama.
  std::ofstream(dir + "/missing.json") << R"({"train": ["a_1k.hdr"], "test": ["gone_1k.hdr"]})";
  expect_error("--data " + panos + " --hdri-split " + dir + "/missing.json", "gone_1k.hdr");
  // A panorama folder holding a non-image.
  const std::string junk = dir + "/junk";
  fs::create_directories(junk);
  std::ofstream(junk + "/notes_1k.hdr") << "this is not an image\n";
  expect_error("--data " + junk, "notes_1k.hdr");
  // A truncated EXR.
  const std::string trunc = dir + "/trunc";
  fs::create_directories(trunc);
  fs::copy_file(panos + "/c_1k.exr", trunc + "/c_1k.exr");
  fs::resize_file(trunc + "/c_1k.exr", fs::file_size(trunc + "/c_1k.exr") / 2);
  expect_error("--data " + trunc, "c_1k.exr");
  // A panorama that is not 2:1.
  const std::string odd = dir + "/odd";
  fs::create_directories(odd);
  sl::data::write_image(odd + "/square_1k.hdr", sl::Tensor::uniform({3, 32, 32}, 0.1, 1.0, 3));
  expect_error("--data " + odd, "square_1k.hdr");
}

}  // namespace sl::test

namespace sl::test {

TEST(EvalTool, LdrPanoramaCropsShowTheLabelledSunWhereTheirCameraProjectsIt) {
  const std::string dir = sl::test::tool_dir("eval_ldr_crops");
  const std::string folder = tiny_ldr_folder(dir);
  const sl::data::SunLabels labels = sl::data::read_sun_labels(folder + "/sun_labels.csv");
  const auto set = sl::train::ldr_panorama_crops({folder + "/a.jpg", folder + "/b.jpg", folder + "/c.jpg"}, labels, 16, 7);
  ASSERT_EQ(set.crops.size(), 32u);  // c has no sun position
  ASSERT_EQ(set.not_scored.size(), 1u);
  EXPECT_EQ(set.not_scored[0]->file, "c.jpg");
  int inside = 0;
  for (const auto& c : set.crops) {
    const auto& v = c.sample.views[0];
    const sl::render::Projection p = v.camera.project(v.camera.position() + 1e3 * c.sample.sun_direction);
    ASSERT_EQ(p.in_image, c.sun_in_crop);
    EXPECT_NEAR(glm::length(sl::train::canonical_frame(v.camera).direction(c.sample.sun_direction) - c.sun_canonical), 0.0,
                1e-12);
    if (!p.in_image) continue;
    ++inside;
    // The crop holds the 8-bit codes: white (1.0) at the projected sun, not decoded to linear.
    const sl::Tensor img = v.ldr.contiguous();
    const int w = static_cast<int>(img.size(2)), h = static_cast<int>(img.size(1));
    float peak = 0.0f;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const int x = std::clamp(static_cast<int>(p.pixel.x) + dx, 0, w - 1);
        const int y = std::clamp(static_cast<int>(p.pixel.y) + dy, 0, h - 1);
        peak = std::max(peak, img.data<float>()[y * w + x]);
      }
    EXPECT_GT(peak, 0.95f) << c.sample.id;
  }
  EXPECT_GT(inside, 0) << "no crop contained a sun";
  // The rotated panorama's sun texel is at the rotated label: pano_ldr (codes) is white there.
  for (const auto& c : set.crops) {
    const sl::Tensor& pano = c.sample.pano_ldr;
    const glm::dvec3 d = c.sample.sun_direction;
    const auto uv = sl::render::equirect::direction_to_uv(d.x, d.y, d.z, static_cast<int>(pano.size(2)),
                                                          static_cast<int>(pano.size(1)));
    float rgb[3];
    sl::data::sample_bilinear(pano.data<float>(), 3, static_cast<int>(pano.size(1)), static_cast<int>(pano.size(2)),
                              uv.u, uv.v, rgb);
    EXPECT_GT(rgb[0], 0.9f) << c.sample.id;  // the 3×3 sun (sky 0.55, ground 0.25), area-resized to 256×128
  }
}

TEST(EvalTool, LdrPanoramasAreReportedApartBySceneBesideTheirBaselineAndListWhatIsNotScored) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP() << "streetlight-eval not built";
  const std::string dir = sl::test::tool_dir("eval_ldr");
  const std::string folder = tiny_ldr_folder(dir);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --name tiny --data " + folder +
                                                          " --ldr-split " + dir + "/ldr_split.json --crops 3 --view-rows 8 --out " +
                                                          dir + "/out");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/out/results.json");
  const auto j = nlohmann::json::parse(jf);
  const auto& d = j["datasets"][0];
  EXPECT_EQ(d["kind"], "ldr_panoramas");
  EXPECT_EQ(d["sun_labels"], folder + "/sun_labels.csv");  // the default: beside the images
  EXPECT_EQ(d["panoramas"]["scored"], nlohmann::json({"a.jpg", "b.jpg"}));
  EXPECT_EQ(d["panoramas"]["low_confidence"], nlohmann::json({"b.jpg"}));
  ASSERT_EQ(d["panoramas"]["not_scored"].size(), 2u);
  EXPECT_EQ(d["panoramas"]["not_scored"][0]["file"], "c.jpg");
  EXPECT_EQ(d["panoramas"]["not_scored"][0]["sun"], "none");
  EXPECT_EQ(d["panoramas"]["not_scored"][1]["file"], "d.jpg");
  EXPECT_EQ(d["panoramas"]["not_scored"][1]["sun"], "occluded");
  const auto& res = d["results"][0];
  EXPECT_EQ(res["images"], 6);  // 3 crops of each scored test panorama
  for (const auto* row : {&res, &d["baseline"]}) {
    const auto& sun = (*row)["sun"];
    EXPECT_EQ(sun["all"]["count"], 6) << row->dump();
    EXPECT_EQ(sun["all"]["count"].get<int>(), sun["sun_in_crop"]["count"].get<int>() + sun["sun_outside_crop"]["count"].get<int>());
    // a is a street, b another scene; b's label is the low-confidence one.
    EXPECT_EQ((*row)["sun_by_scene"]["street"]["all"]["count"], 3) << row->dump();
    EXPECT_EQ((*row)["sun_by_scene"]["other"]["all"]["count"], 3) << row->dump();
    EXPECT_EQ((*row)["sun_low_confidence"]["all"]["count"], 3) << row->dump();
    for (const char* k : {"street", "other"})
      for (const char* part : {"all", "sun_in_crop", "sun_outside_crop"})
        EXPECT_TRUE((*row)["sun_by_scene"][k].contains(part)) << k << "." << part;
  }
  // The sun head's confidence halves per scene (null here: the tiny model has no sun head).
  ASSERT_TRUE(res.contains("sun_confidence_probability_by_scene")) << res.dump();
  EXPECT_TRUE(res["sun_confidence_probability_by_scene"]["street"].is_null());
  // Per crop: the label's class, confidence and scene, and the true sun of the library's crops.
  const sl::data::SunLabels labels = sl::data::read_sun_labels(folder + "/sun_labels.csv");
  const auto crops = sl::train::ldr_panorama_crops({folder + "/a.jpg", folder + "/b.jpg"}, labels, 3, 0x7265616c736b79ULL);
  const auto& per = res["sun_per_image"];
  ASSERT_EQ(per.size(), 6u);
  for (size_t i = 0; i < per.size(); ++i) {
    const bool a = per[i]["id"].get<std::string>().rfind("a.jpg#", 0) == 0;
    EXPECT_EQ(per[i]["scene"], a ? "street" : "other") << per[i].dump();
    EXPECT_EQ(per[i]["label"], a ? "visible" : "occluded") << per[i].dump();
    EXPECT_EQ(per[i]["confidence"], a ? "high" : "low") << per[i].dump();
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(per[i]["truth"][k].get<double>(), crops.crops[i].sun_canonical[k], 1e-9);
  }
  // Confidence, by each measure: the median error of the half with the smallest values against the
  // rest's. The hedge is the predicted sun's height: sin(elevation) of its canonical direction.
  for (const auto& [key, measure] : std::vector<std::pair<std::string, std::string>>{
           {"sun_confidence", "sun_flip_spread_deg"}, {"sun_confidence_hedge", "sun_hedge"}}) {
    std::vector<std::pair<double, double>> value_error;
    for (const auto& e : per) value_error.emplace_back(e[measure].get<double>(), e["sun_error_deg"].get<double>());
    std::stable_sort(value_error.begin(), value_error.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    auto median3 = [](std::vector<double> v) { std::sort(v.begin(), v.end()); return v[1]; };
    const auto& conf = res[key];
    EXPECT_EQ(conf["measure"], measure);
    EXPECT_EQ(conf["confident_half"]["count"], 3);
    EXPECT_EQ(conf["uncertain_half"]["count"], 3);
    EXPECT_NEAR(conf["confident_half"]["sun_error_median_deg"].get<double>(),
                median3({value_error[0].second, value_error[1].second, value_error[2].second}), 1e-9);
    EXPECT_NEAR(conf["uncertain_half"]["sun_error_median_deg"].get<double>(),
                median3({value_error[3].second, value_error[4].second, value_error[5].second}), 1e-9);
    EXPECT_LE(conf["confident_half"]["measure_max"].get<double>(), conf["uncertain_half"]["measure_min"].get<double>());
  }
  for (const auto& e : per) {
    if (e["visible_sun_found"].get<bool>()) continue;
    EXPECT_NEAR(e["sun_hedge"].get<double>(), std::clamp(e["predicted"][1].get<double>(), 0.0, 1.0), 1e-6) << e.dump();
    EXPECT_GT(e["predicted_sun_share"].get<double>(), 0.0) << e.dump();
  }
  // The baseline: the training split's labelled suns, as the library computes it.
  const auto& b = d["baseline"];
  EXPECT_EQ(b["from_panoramas"], nlohmann::json({"t1.jpg", "t2.jpg"}));
  const auto train = sl::train::ldr_panorama_crops({folder + "/t1.jpg", folder + "/t2.jpg"}, labels, 3, 0x7265616c736b79ULL,
                                                   sl::train::real_sky_crop_options(), false);
  const glm::dvec3 expect = sl::train::constant_baseline_direction(train.crops);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(b["direction"][k].get<double>(), expect[k], 1e-9);
  std::ifstream mf(dir + "/out/results.md");
  const std::string md((std::istreambuf_iterator<char>(mf)), std::istreambuf_iterator<char>());
  for (const char* s : {"real LDR panoramas", "Street scenes", "Other scenes", "Low-confidence", "constant baseline",
                        "not scored (no sun position): 2", "c.jpg (none)", "most confident half"})
    EXPECT_NE(md.find(s), std::string::npos) << s << " in\n" << md;
  EXPECT_EQ(md.find("0.0 (0)"), std::string::npos) << "an empty part prints a dash, not a median of 0\n" << md;
  // An explicit --sun-labels is read instead of the one beside the images.
  fs::copy_file(folder + "/sun_labels.csv", dir + "/other_labels.csv");
  const auto r2 = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + folder + " --ldr-split " + dir +
                                                           "/ldr_split.json --sun-labels " + dir +
                                                           "/other_labels.csv --crops 1 --view-rows 8 --json");
  ASSERT_EQ(r2.code, 0) << r2.out;
  const auto j2 = nlohmann::json::parse(r2.out.substr(r2.out.find('{')));
  EXPECT_EQ(j2["datasets"][0]["sun_labels"], dir + "/other_labels.csv");
  EXPECT_EQ(j2["datasets"][0]["results"][0]["images"], 2);
  // Without flip averaging there is no spread, so no confidence split; without the visible-sun
  // cue it never fires.
  const auto r3 = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + folder + " --ldr-split " + dir +
                                                           "/ldr_split.json --crops 1 --view-rows 8 --no-flip-average "
                                                           "--no-visible-sun --json");
  ASSERT_EQ(r3.code, 0) << r3.out;
  const auto j3 = nlohmann::json::parse(r3.out.substr(r3.out.find('{')));
  EXPECT_TRUE(j3["datasets"][0]["results"][0]["sun_confidence"].is_null());
  EXPECT_FALSE(j3["datasets"][0]["results"][0]["sun_confidence_hedge"].is_null());  // the hedge needs no mirror pass
  EXPECT_TRUE(j3["datasets"][0]["results"][0]["sun_per_image"][0]["sun_flip_spread_deg"].is_null());
  EXPECT_EQ(j3["datasets"][0]["results"][0]["visible_sun"], false);
  EXPECT_EQ(j3["datasets"][0]["results"][0]["sun_per_image"][0]["visible_sun_found"], false);
  EXPECT_EQ(j3["datasets"][0]["results"][0]["sun"]["sun_in_crop"]["visible_sun_fired"].get<size_t>() +
                j3["datasets"][0]["results"][0]["sun"]["sun_outside_crop"]["visible_sun_fired"].get<size_t>(),
            0u);
  EXPECT_EQ(j2["datasets"][0]["results"][0]["visible_sun"], true);  // the default
}

TEST(EvalTool, BadSunLabelsAreOneLineNamingTheFileAndLine) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("eval_ldr_bad");
  const std::string folder = tiny_ldr_folder(dir);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  auto run = [&](const std::string& labels_body, const std::string& needle, const std::string& extra = "") {
    std::ofstream(dir + "/bad.csv") << labels_body;
    const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + folder + " --ldr-split " +
                                                            dir + "/ldr_split.json --sun-labels " + dir + "/bad.csv " +
                                                            extra + "--out " + dir + "/res");
    sl::test::expect_clean_error(r, dir + "/res", needle);
  };
  const std::string h = "file,sun,u,v,confidence,scene,note\n";
  run(h + "a.jpg,visible,488,328,high,street,\nb.jpg,sunny,1,1,high,street,\n", dir + "/bad.csv:3");
  run(h + "a.jpg,visible,4000,328,high,street,\n", dir + "/bad.csv:2");
  run(h + "a.jpg,visible,488,328,certain,street,\n", "unknown confidence 'certain'");
  run(h + "a.jpg,visible,488,328,high,beach,\n", "unknown scene 'beach'");
  run("file,sun,u,v,scene\na.jpg,none,,,street\n", dir + "/bad.csv:1");
  run(h + "a.jpg,visible,488,328,high\n", "missing column 'scene'");
  // A test panorama without a label names the panorama and the labels file.
  run(h + "a.jpg,visible,488,328,high,street,\nt1.jpg,none,,,high,street,\nt2.jpg,none,,,high,street,\n", "b.jpg");
  // A missing labels file.
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + folder +
                                                          " --sun-labels " + dir + "/gone.csv --out " + dir + "/out/res");
  sl::test::expect_clean_error(r, dir + "/res", "gone.csv");
}

}  // namespace sl::test
