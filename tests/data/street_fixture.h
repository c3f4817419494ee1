// A tiny generated street dataset shared by the data tests (one per test process; rendering it
// takes well under a second at these sizes).
#pragma once
#include <filesystem>
#include <string>

#include "data/street_generator.h"
#include "test_files.h"

namespace sl::test {

// The generator's defaults shrunk to thumbnail size and a few samples per pixel.
inline nlohmann::json tiny_generator_tree(int samples = 3) {
  nlohmann::json t = street_generator_defaults();
  t["samples"] = samples;
  t["seed"] = 7;
  t["render"] = {{"spp", 2}, {"max_depth", 2}, {"environment_width", 64}};
  t["panorama"] = {{"width", 32}, {"height", 16}};
  t["views"]["width"] = 48;
  t["views"]["height"] = 24;
  t["sky"]["width"] = 32;
  t["sky"]["height"] = 8;
  t["insertion"]["min_visible_pixels"] = 4;
  t["insertion"]["coverage_samples"] = 2;
  t["splits"] = {{"train", 0.34}, {"val", 0.33}};
  return t;
}

// Generates the tiny dataset once into `<scratch>/<name>` and returns the folder.
inline std::string tiny_dataset(const std::string& name = "tiny_dataset", int samples = 3) {
  const std::string out = scratch(name);
  if (std::filesystem::exists(std::filesystem::path(out) / "index.json")) return out;
  const StreetGeneratorConfig c = street_generator_config(tiny_generator_tree(samples));
  std::vector<std::string> ids;
  std::filesystem::create_directories(std::filesystem::path(out) / "samples");
  for (int64_t i = 0; i < c.samples; ++i) ids.push_back(generate_street_sample(c, i, out + "/samples").id);
  write_dataset_index(out, c, split_ids(ids, c.seed, c.train_fraction, c.val_fraction));
  return out;
}

}  // namespace sl::test
