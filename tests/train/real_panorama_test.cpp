// Real panoramas in stages 2-3 (train/sample_source.h, train/real_sky_benchmark.h): the
// radiance-consistency loss is zero for an oracle that returns the panorama itself and positive
// otherwise; mixed sources draw both kinds and vary the crop with the draw; the constant
// baseline is the mean training sun and nothing else.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "data/ldr_panorama_sample.h"
#include "data/panorama.h"
#include "data/sky_model.h"
#include "render/environment_map.h"
#include "train/losses.h"
#include "train/real_sky_benchmark.h"
#include "train/sample_source.h"
#include "train/street_batch.h"
#include "util/error.h"
#include "util/math.h"

using sl::data::panorama_street_sample;
using sl::data::PanoramaSampleOptions;
using sl::data::PreethamSky;
using sl::data::rotate_azimuth;
using sl::data::SkyParams;
using sl::data::StreetSample;
using sl::render::env_lookup;
using sl::render::VsgGrid;

namespace sl::test {
using train::RealSkyCrop;
using train::SampleSource;
using train::StreetBatchOptions;
using train::StreetItem;
using train::SunErrorStats;
using train::constant_baseline_direction;
using train::is_ldr_panorama_folder;
using train::load_ldr_panorama_folder;
using train::make_street_item;
using train::mixed_source;
using train::radiance_l2;
using train::sun_error_stats;

namespace {

Tensor clear_sky(double elevation_deg, double azimuth_deg) {
  SkyParams p;
  p.sun_elevation_rad = elevation_deg * kPi / 180.0;
  p.sun_azimuth_rad = azimuth_deg * kPi / 180.0;
  return PreethamSky(p).render(64, 128);
}

TEST(RealPanorama, RadianceConsistencyIsZeroForThePanoramaItselfAndPositiveOtherwise) {
  PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 128;  // the sample keeps the panorama at full resolution: the oracle is exact
  o.pano_height = 64;
  const StreetSample s = panorama_street_sample(clear_sky(30.0, 45.0), "oracle", 3, 1, o);
  VsgGrid grid;
  grid.dims = {8, 8, 4};
  StreetBatchOptions bo;
  bo.pano_rays = 300;
  bo.view_rays = 300;
  bo.need_volume = false;
  const StreetItem it = make_street_item(s, 0, grid, bo, 11, 0);
  // Eq. 1 queried from the camera centre: an oracle light field that IS the panorama (in the
  // item's canonical frame, exposure-normalised) along the crop's rays and the sphere's rays.
  const Tensor oracle_env = mul_scalar(it.frame.panorama(s.pano_hdr.contiguous()), s.exposure).contiguous();
  const Tensor dirs = it.directions.to(DType::F32);
  const Tensor oracle = env_lookup(oracle_env, dirs);
  const double exact = radiance_l2(oracle, it.target_ldr.to(DType::F32)).item();
  EXPECT_LT(exact, 1e-6);
  const double brighter = radiance_l2(mul_scalar(oracle, 1.5), it.target_ldr.to(DType::F32)).item();
  EXPECT_GT(brighter, 1e-3);
  const Tensor rolled = env_lookup(rotate_azimuth(oracle_env, 0.5).contiguous(), dirs);
  EXPECT_GT(radiance_l2(rolled, it.target_ldr.to(DType::F32)).item(), 1e-4);
  // No depth loss where there is no depth: every target distance is unknown.
  for (double d : it.target_distance.to_vector()) EXPECT_TRUE(std::isnan(d));
}

// An LDR street panorama (codes / 255) with a clipped sun: what data/ldr_panorama_sample.h reads.
Tensor ldr_street(int width) {
  const Tensor t = data::resize_area(clear_sky(25.0, 60.0), width / 2, width).contiguous();
  return data::to_ldr(t, render::exposure_for_ldr_median(t, 0.4));
}

TEST(RealPanorama, LdrRadianceConsistencyIsZeroForThePanoramaItselfAndPositiveOtherwise) {
  PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 128;  // the working size: the sample's panorama is the one its crop reads
  o.pano_height = 64;
  o.exposure_stops = 1.0;  // jittered and flipped: the oracle is the sample's own panorama
  data::LdrPanorama pano;
  pano.ldr = ldr_street(128);
  pano.sky_mask = data::ldr_sky_mask(pano.ldr);
  for (uint64_t stream : {1u, 2u, 5u}) {
    const StreetSample s = data::ldr_panorama_street_sample(pano, "ldr:oracle", 3, stream, o);
    VsgGrid grid;
    grid.dims = {8, 8, 4};
    StreetBatchOptions bo;
    bo.pano_rays = 300;
    bo.view_rays = 300;
    bo.need_volume = false;
    const StreetItem it = make_street_item(s, 0, grid, bo, 11, stream);
    // LDR terms (clipped, γ 2.2): the oracle light field is the panorama's linear radiance,
    // codes^2.2, in the item's canonical frame; its LDR along every ray is the captured code.
    const Tensor oracle_env = it.frame.panorama(s.pano_hdr.contiguous()).contiguous();
    const Tensor dirs = it.directions.to(DType::F32);
    const Tensor oracle = env_lookup(oracle_env, dirs);
    EXPECT_LT(radiance_l2(oracle, it.target_ldr.to(DType::F32)).item(), 1e-6) << "stream " << stream;
    EXPECT_GT(radiance_l2(mul_scalar(oracle, 0.5), it.target_ldr.to(DType::F32)).item(), 1e-3);
    const Tensor rolled = env_lookup(rotate_azimuth(oracle_env, 0.5).contiguous(), dirs);
    EXPECT_GT(radiance_l2(rolled, it.target_ldr.to(DType::F32)).item(), 1e-4);
    for (double d : it.target_distance.to_vector()) EXPECT_TRUE(std::isnan(d));
  }
}

// The sun's energy is a label where the sky is HDR (a hard-sun HDR crop, and its mirror image,
// with the same energy), and none for an LDR panorama, whose sun is clipped.
TEST(RealPanorama, TheSunsEnergyIsKnownForHdrSkiesOnly) {
  PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 128;
  o.pano_height = 64;
  VsgGrid grid;
  grid.dims = {8, 8, 4};
  StreetBatchOptions bo;
  bo.pano_rays = 8;
  bo.view_rays = 8;
  bo.need_volume = false;
  const StreetSample hdr = panorama_street_sample(clear_sky(30.0, 45.0), "hdri:sky", 3, 1, o);
  ASSERT_TRUE(hdr.sun_known);
  const StreetItem a = make_street_item(hdr, 0, grid, bo, 1, 0);
  const StreetItem b = make_street_item(data::flip_sample(hdr), 0, grid, bo, 1, 0);
  ASSERT_TRUE(a.sun_energy_known && b.sun_energy_known);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_GT(a.sun_energy[ch], 0.0);
    EXPECT_NEAR(b.sun_energy[ch], a.sun_energy[ch], 1e-9 * a.sun_energy[ch]);
  }
  data::LdrPanorama pano;
  pano.ldr = ldr_street(128);
  pano.sky_mask = data::ldr_sky_mask(pano.ldr);
  pano.sun_known = true;
  const StreetSample ldr = data::ldr_panorama_street_sample(pano, "ldr:p", 3, 1, o);
  EXPECT_FALSE(ldr.hdr_sky);
  EXPECT_FALSE(make_street_item(ldr, 0, grid, bo, 1, 0).sun_energy_known);
}

TEST(RealPanorama, MixedSourceDrawsBothKindsAndANewCropPerDraw) {
  SampleSource streets{6, [](size_t i, uint64_t) {
                         StreetSample s;
                         s.id = "street" + std::to_string(i);
                         return s;
                       }};
  const Tensor pano = clear_sky(50.0, 0.0);
  SampleSource real{1, [pano](size_t, uint64_t draw) {
                      PanoramaSampleOptions o;
                      o.crop.width = 32;
                      o.crop.height = 16;
                      o.pano_width = 64;
                      o.pano_height = 32;
                      return panorama_street_sample(pano, "hdri:sky", 0, draw, o);
                    }};
  const SampleSource mixed = mixed_source(streets, real, 0.5);
  EXPECT_EQ(mixed.size, 12u);
  EXPECT_EQ(mixed.load(0, 0).id, "street0");
  EXPECT_EQ(mixed.load(6, 0).id, "hdri:sky");
  EXPECT_NE(mixed.load(6, 1).views[0].ldr.to_vector(), mixed.load(6, 2).views[0].ldr.to_vector());
  EXPECT_EQ(mixed.load(6, 1).views[0].ldr.to_vector(), mixed.load(11, 1).views[0].ldr.to_vector());
}

TEST(RealSkyBenchmark, BaselineIsTheMeanTrainingSunInTheCropFrame) {
  // Three "panoramas" as crops: the baseline only sees the ones it is given.
  auto crop = [](const glm::dvec3& sun, bool known) {
    RealSkyCrop c;
    c.sun_canonical = glm::normalize(sun);
    c.sun_known = known;
    return c;
  };
  const std::vector<RealSkyCrop> train = {crop({1, 1, 0}, true), crop({-1, 1, 0}, true), crop({0, -1, 0}, false)};
  const glm::dvec3 b = constant_baseline_direction(train);
  EXPECT_NEAR(b.x, 0.0, 1e-12);
  EXPECT_NEAR(b.y, 1.0, 1e-12);  // the unknown sun is ignored
  const SunErrorStats s = sun_error_stats({5.0, 20.0, 40.0, 80.0});
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.median_deg, 30.0);
  EXPECT_DOUBLE_EQ(s.within_15, 0.25);
  EXPECT_DOUBLE_EQ(s.within_30, 0.5);
  EXPECT_DOUBLE_EQ(s.within_45, 0.75);
}

// What streetlight-eval reads as a folder of labelled LDR panoramas, and the error that names a
// folder whose labels are missing.
TEST(RealSkyBenchmark, LdrPanoramaFoldersAreRecognisedAndTheirLabelsRequired) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("sl_ldr_folder_" + std::to_string(::getpid()));
  fs::remove_all(root);
  for (const char* d : {"labelled", "jpegs", "mixed", "empty"}) fs::create_directories(root / d);
  std::ofstream(root / "labelled" / "sun_labels.csv") << "file,sun,u,v,confidence,scene,note\n";
  std::ofstream(root / "jpegs" / "a.JPG") << "x";
  std::ofstream(root / "mixed" / "a.jpg") << "x";
  std::ofstream(root / "mixed" / "sky.hdr") << "x";
  EXPECT_TRUE(is_ldr_panorama_folder((root / "labelled").string()));
  EXPECT_TRUE(is_ldr_panorama_folder((root / "jpegs").string()));
  EXPECT_FALSE(is_ldr_panorama_folder((root / "mixed").string()));
  EXPECT_FALSE(is_ldr_panorama_folder((root / "empty").string()));
  const std::string labels = (root / "jpegs" / "sun_labels.csv").string();
  try {
    load_ldr_panorama_folder((root / "jpegs").string(), labels, "", "test", 1);
    ADD_FAILURE() << "a folder without its labels file was loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no sun labels '" + labels + "'"), std::string::npos) << e.what();
  }
  fs::remove_all(root);
}

}  // namespace
}  // namespace sl::test
