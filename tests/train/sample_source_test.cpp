// The decoded-sample cache of dataset_source (data.cache_mb): a hit returns the first load's
// tensors without reading the folder again, a sample that does not fit is decoded every time, and
// a lighting stage trained over several epochs with the cache matches one without it bit for bit.
#include "train/sample_source.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "data/image_io.h"
#include "support/street_fixture.h"
#include "support/tiny_stage.h"
#include "train/lighting_stage.h"
#include "train/train_config.h"
#include "util/error.h"

namespace sl::test {
using data::StreetSample;
using train::dataset_source;
using train::LightingStage;
using train::SampleSource;
using train::kStageLighting;
using train::sample_bytes;

namespace {

namespace fs = std::filesystem;

std::vector<double> values(const Tensor& t) { return t.to_vector(); }

void expect_same_sample(const StreetSample& a, const StreetSample& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(values(a.pano_hdr), values(b.pano_hdr));
  EXPECT_EQ(values(a.sky_hdr), values(b.sky_hdr));
  ASSERT_EQ(a.views.size(), b.views.size());
  for (size_t v = 0; v < a.views.size(); ++v) {
    EXPECT_EQ(values(a.views[v].ldr), values(b.views[v].ldr));
    EXPECT_EQ(values(a.views[v].depth), values(b.views[v].depth));
  }
  EXPECT_EQ(sample_bytes(a), sample_bytes(b));
}

// A private copy of the tiny dataset, so that a test may delete its files.
std::string copy_of_tiny_dataset(const std::string& name) {
  const std::string src = tiny_dataset("sample_cache_dataset", 6);
  const std::string dst = temp_dir(name);
  fs::copy(src, dst, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  return dst;
}

// The ids the real-panorama sources write are the ones the stage reads back to group its errors
// and label its domain classifier: "hdri:<file>#<stream>", "ldr:<file>#<stream>", else a street.
TEST(SampleSource, CropIdsNameTheirOriginAndEveryOtherIdIsAStreet) {
  using train::SampleOrigin;
  EXPECT_EQ(train::crop_sample_id(SampleOrigin::HdrCrop, "sky.exr", 7), "hdri:sky.exr#7");
  EXPECT_EQ(train::crop_sample_id(SampleOrigin::LdrCrop, "street.jpg", 0), "ldr:street.jpg#0");
  for (SampleOrigin o : {SampleOrigin::HdrCrop, SampleOrigin::LdrCrop})
    EXPECT_EQ(train::sample_origin(train::crop_sample_id(o, "a#b:c", 123456789012ull)), o);
  for (const char* id : {"", "000012", "hdri", "ldr", "xhdri:a#1", "HDRI:a#1"})
    EXPECT_EQ(train::sample_origin(id), SampleOrigin::Street) << id;
  EXPECT_THROW(train::crop_sample_id(SampleOrigin::Street, "a", 0), sl::Error);
}

TEST(SampleSource, CachedSampleIsTheDecodedOneAndSurvivesItsFolder) {
  const std::string dir = copy_of_tiny_dataset("cache_hit");
  const SampleSource plain = dataset_source(dir, "train");
  const SampleSource cached = dataset_source(dir, "train", 0, size_t{1} << 30);
  ASSERT_GE(cached.size, 1u);
  const StreetSample first = cached.load(0, 0);
  EXPECT_GT(sample_bytes(first), 0u);
  expect_same_sample(first, plain.load(0, 0));
  // The folder goes: the cached source still answers from memory, the plain one names the file.
  fs::remove_all(fs::path(dir) / "samples" / first.id);
  const StreetSample again = cached.load(0, 7);
  expect_same_sample(again, first);
  EXPECT_EQ(again.pano_hdr.data<float>(), first.pano_hdr.data<float>());  // the same storage: no copy
  EXPECT_THROW(plain.load(0, 0), Error);
}

TEST(SampleSource, SampleLargerThanTheCacheIsDecodedEveryTime) {
  const std::string dir = copy_of_tiny_dataset("cache_too_small");
  const SampleSource cached = dataset_source(dir, "train", 0, 16);  // 16 bytes: nothing fits
  const StreetSample first = cached.load(0, 0);
  const StreetSample again = cached.load(0, 0);
  expect_same_sample(again, first);
  EXPECT_NE(again.pano_hdr.data<float>(), first.pano_hdr.data<float>());
  fs::remove_all(fs::path(dir) / "samples" / first.id);
  EXPECT_THROW(cached.load(0, 0), Error);
}

// Six steps of batch 2 over a split of 2 samples: every sample is drawn six times, five of them
// from the cache. Losses and weights match the uncached run exactly.
TEST(SampleSource, CacheChangesNoLossAndNoWeight) {
  const std::string dir = tiny_dataset("sample_cache_dataset", 6);
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, temp_dir("cache_training"));
  c["data"]["flip"] = true;  // the flip builds new tensors from the cached ones
  std::vector<std::vector<double>> losses(2);
  std::vector<std::vector<std::vector<double>>> weights(2);
  for (int run = 0; run < 2; ++run) {
    const size_t cache = run == 0 ? 0 : size_t{1} << 30;
    SampleSource train = dataset_source(dir, "train", 0, cache);
    ASSERT_GE(train.size, 1u);
    ASSERT_LE(train.size, 3u);  // so that six steps of batch 2 draw every sample several times
    LightingStage stage(c, std::move(train), dataset_source(dir, "val", 1));
    stage.initialise();
    for (int64_t step = 0; step < 6; ++step) {
      stage.set_lr(3e-3);
      losses[run].push_back(stage.step(step).at("loss"));
    }
    for (const auto& [name, p] : stage.model().named_parameters()) weights[run].push_back(p.to_vector());
  }
  EXPECT_EQ(losses[0], losses[1]);
  ASSERT_EQ(weights[0].size(), weights[1].size());
  for (size_t i = 0; i < weights[0].size(); ++i) EXPECT_EQ(weights[0][i], weights[1][i]) << "parameter " << i;
}

TEST(SampleSource, CacheSizeMustBeANonNegativeMebibyteCount) {
  nlohmann::json c = train::default_train_config();
  c["stage"] = kStageLighting;
  c["init"]["sky_checkpoint"] = "sky.safetensors";
  c["data"]["dataset"] = "streets";
  c["data"]["cache_mb"] = 0;
  EXPECT_NO_THROW(train::check_train_config(c));
  c["data"]["cache_mb"] = -1;
  try {
    train::check_train_config(c);
    ADD_FAILURE() << "accepted data.cache_mb = -1";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("data.cache_mb"), std::string::npos) << e.what();
  }
}

}  // namespace

// Place balance (data.ldr_place_balance): three LDR panoramas, two of place A and one of B. The
// default cycle draws B a third of the time, and exponent 1 with places given draws exactly the
// same crops; exponent 0 gives each place half the draws.
TEST(SampleSource, PlaceBalanceGivesEachPlaceItsShare) {
  const std::string dir = temp_dir("place_balance");
  const Tensor ldr = Tensor::full({3, 32, 64}, 0.5);
  data::ImageWriteOptions wo;
  wo.transfer = data::Transfer::Linear;
  {
    std::ofstream csv(dir + "/sun_labels.csv");
    csv << "file,sun,u,v,confidence,scene,note\n";
    for (const char* f : {"a1.png", "a2.png", "b.png"}) {
      data::write_image(dir + "/" + f, ldr, wo);
      csv << f << ",none,,,high,street,\n";
    }
  }
  const std::vector<std::string> paths = {dir + "/b.png", dir + "/a1.png", dir + "/a2.png"};
  data::PanoramaSampleOptions o;
  o.crop.width = 16;
  o.crop.height = 8;
  o.pano_width = 32;
  o.pano_height = 16;
  const std::string labels = dir + "/sun_labels.csv";
  train::LdrPlaceBalance same;
  same.places = {"B", "A", "A"};
  train::LdrPlaceBalance places = same;
  places.exponent = 0.0;
  const SampleSource cycle = train::ldr_panorama_source(paths, labels, o, 7, 3, true, 64);
  const SampleSource one = train::ldr_panorama_source(paths, labels, o, 7, 3, true, 64, same);
  const SampleSource balanced = train::ldr_panorama_source(paths, labels, o, 7, 3, true, 64, places);
  const int draws = 600;
  int b_cycle = 0, b_balanced = 0;
  for (int d = 0; d < draws; ++d) {
    const auto i = static_cast<size_t>(d % 3);
    const StreetSample s = cycle.load(i, static_cast<uint64_t>(d));
    EXPECT_EQ(s.id, one.load(i, static_cast<uint64_t>(d)).id);
    b_cycle += s.id.rfind("ldr:b.png#", 0) == 0;
    b_balanced += balanced.load(i, static_cast<uint64_t>(d)).id.rfind("ldr:b.png#", 0) == 0;
  }
  EXPECT_EQ(b_cycle, draws / 3);
  // Binomial(600, 0.5): sd 12.2, so ±61 is five of them.
  EXPECT_NEAR(b_balanced, draws / 2, 61);
  // A pure function of (index, draw): the same draw twice is the same crop.
  EXPECT_EQ(balanced.load(0, 123).id, balanced.load(2, 123).id);
  // The places must come one per panorama.
  train::LdrPlaceBalance short_list = places;
  short_list.places.pop_back();
  EXPECT_THROW(train::ldr_panorama_source(paths, labels, o, 7, 3, true, 64, short_list), Error);
}

}  // namespace sl::test
