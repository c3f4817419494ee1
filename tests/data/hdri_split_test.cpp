// The committed scene-disjoint splits of the shared real panoramas (configs/hdri_split.json for
// ../shared/data/hdri, configs/pano_ldr_split.json for ../shared/data/pano_ldr): the split reader
// accepts them, every file of each folder is in exactly one split, and the places MANIFEST.md
// names never straddle two splits.
#include "data/hdri_split.h"
#include "data/places.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>

#include "data/sun_labels.h"
#include "support/test_files.h"
#include "util/error.h"

using sl::data::HdriSplit;
using sl::data::read_hdri_split;

namespace sl::test {

namespace fs = std::filesystem;

namespace {

std::string config(const std::string& name) { return std::string(STREETLIGHT_SOURCE_DIR) + "/configs/" + name; }

// file name → its split.
std::map<std::string, std::string> split_of(const HdriSplit& s) {
  std::map<std::string, std::string> m;
  for (const auto& [split, names] : s.splits)
    for (const auto& n : names) m[n] = split;
  return m;
}

std::set<std::string> images_in(const std::string& folder, const std::set<std::string>& extensions) {
  std::set<std::string> out;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.is_regular_file() && extensions.count(e.path().extension().string())) out.insert(e.path().filename().string());
  return out;
}

// Every file of `folder` is listed once (the reader refuses a name in two splits) and every listed
// name is a file of the folder; split_paths finds each.
void expect_covers_exactly(const HdriSplit& s, const std::string& folder, const std::set<std::string>& files) {
  const auto m = split_of(s);
  for (const auto& f : files) EXPECT_TRUE(m.count(f)) << f << " is in no split of " << s.file;
  for (const auto& [name, split] : m) EXPECT_TRUE(files.count(name)) << name << " (" << split << ") is not in " << folder;
  size_t listed = 0;
  for (const char* split : {"train", "val", "test"}) {
    ASSERT_TRUE(s.has(split)) << split;
    listed += s.split_paths(folder, split).size();
  }
  EXPECT_EQ(listed, files.size());
  EXPECT_EQ(s.splits.size(), 3u);
}

// Each group's files share one split.
void expect_groups_whole(const std::map<std::string, std::string>& split, const std::map<std::string, std::set<std::string>>& groups) {
  for (const auto& [group, files] : groups) {
    std::set<std::string> splits;
    for (const auto& f : files) {
      ASSERT_TRUE(split.count(f)) << f;
      splits.insert(split.at(f));
    }
    EXPECT_EQ(splits.size(), 1u) << "place '" << group << "' straddles splits";
  }
}

}  // namespace

TEST(HdriSplit, TheHdriSplitCoversAll64PanoramasAndKeepsTheFirst40WhereTheyWere) {
  const HdriSplit s = read_hdri_split(config("hdri_split.json"));
  const auto split = split_of(s);
  EXPECT_EQ(split.size(), 64u);
  // The assignment of the first 40 files before issue 39 (earlier results stay comparable).
  const std::map<std::string, std::vector<std::string>> before = {
      {"val", {"hilly_terrain_01_1k.hdr", "garden_nook_1k.hdr", "skidpan_1k.hdr", "dikhololo_night_1k.hdr"}},
      {"test", {"wide_street_01_1k.exr", "rooitou_park_1k.hdr", "quarry_02_1k.hdr", "autumn_field_puresky_1k.hdr",
                "ulmer_muenster_1k.exr", "palermo_sidewalk_1k.hdr", "palermo_square_1k.hdr", "potsdamer_platz_1k.hdr",
                "dresden_square_1k.hdr", "forest_slope_1k.hdr"}},
      {"train", {"adams_place_bridge_1k.hdr", "aristea_wreck_puresky_1k.hdr", "chinese_garden_1k.hdr",
                 "crystal_falls_1k.hdr", "dry_cracked_lake_1k.hdr", "immenstadter_horn_1k.hdr",
                 "industrial_sunset_02_1k.hdr", "kiara_1_dawn_1k.hdr", "kloofendal_48d_partly_cloudy_puresky_1k.hdr",
                 "kloppenheim_05_1k.hdr", "kloppenheim_06_puresky_1k.hdr", "modern_buildings_2_1k.hdr",
                 "narrow_moonlit_road_1k.hdr", "noon_grass_1k.hdr", "peppermint_powerplant_1k.hdr",
                 "phalzer_forest_01_1k.hdr", "rainforest_trail_1k.hdr", "round_platform_1k.exr",
                 "rustig_koppie_puresky_1k.hdr", "schadowplatz_1k.hdr", "spree_bank_1k.hdr",
                 "st_peters_square_night_1k.hdr", "urban_street_01_1k.hdr", "venice_sunset_1k.hdr",
                 "wasteland_clouds_puresky_1k.hdr", "evening_road_01_puresky_1k.hdr"}}};
  size_t old = 0;
  for (const auto& [want, names] : before)
    for (const auto& n : names) {
      ASSERT_TRUE(split.count(n)) << n;
      EXPECT_EQ(split.at(n), want) << n;
      ++old;
    }
  EXPECT_EQ(old, 40u);
  // One place (or possibly one place) per group; the new hard suns (MANIFEST: sun5 >= 0.25, peak
  // above the horizon) are spread, and the test split has several hard suns in all.
  expect_groups_whole(split, {{"kloppenheim", {"kloppenheim_01_puresky_1k.hdr", "kloppenheim_05_1k.hdr",
                                               "kloppenheim_06_puresky_1k.hdr", "kloppenheim_07_1k.hdr"}},
                              {"kloofendal", {"kloofendal_43d_clear_puresky_1k.hdr", "kloofendal_48d_partly_cloudy_puresky_1k.hdr"}},
                              {"industrial_sunset", {"industrial_sunset_02_1k.hdr", "industrial_sunset_puresky_1k.hdr"}},
                              {"palermo", {"palermo_sidewalk_1k.hdr", "palermo_square_1k.hdr", "piazza_bologni_1k.hdr"}},
                              {"meadow", {"meadow_2_1k.hdr", "evening_meadow_1k.hdr"}},
                              {"garden", {"garden_nook_1k.hdr", "studio_garden_1k.hdr"}}});
  std::map<std::string, int> hard;
  for (const char* f : {"wide_street_01_1k.exr", "rooitou_park_1k.hdr", "quarry_02_1k.hdr", "autumn_field_puresky_1k.hdr",
                        "ulmer_muenster_1k.exr", "kloofendal_43d_clear_puresky_1k.hdr",
                        "lonely_road_afternoon_puresky_1k.hdr", "meadow_2_1k.hdr", "mpumalanga_veld_puresky_1k.hdr",
                        "rural_asphalt_road_1k.hdr", "san_giuseppe_bridge.exr", "studio_garden_1k.hdr",
                        "sunny_vondelpark_1k.hdr", "syferfontein_18d_clear_1k.hdr", "table_mountain_2_puresky_1k.hdr"})
    ++hard[split.at(f)];
  EXPECT_GE(hard["test"], 8);
  EXPECT_GE(hard["val"], 2);
  EXPECT_GE(hard["train"], 4);
  const std::string folder = shared_data("hdri");
  if (!fs::is_directory(folder)) GTEST_SKIP() << "needs ../shared/data/hdri (not in a fresh clone) for the folder check";
  expect_covers_exactly(s, folder, images_in(folder, {".hdr", ".exr"}));
}

namespace {

// The first split's 69 panoramas (configs/pano_ldr_split_69.json): places from their file names.
// A repository is one place (forks of one repository name are one), except those MANIFEST says
// hold several (googlearchive, All4Gis, pchen66: one place per file, All4Gis' two commits of
// image.jpg together); VGiudicelli1/TSI_panoramax by capture (Strasbourg, Lyon, the car-mounted
// uuid files).
std::map<std::string, std::set<std::string>> first_split_places(const std::map<std::string, std::string>& split) {
  const std::regex uuid("^[0-9a-f]{8}-[0-9a-f]{4}-.*");
  std::map<std::string, std::set<std::string>> places;
  for (const auto& [file, sp] : split) {
    const size_t a = file.find("__"), b = file.find("__", a + 2);
    EXPECT_TRUE(a != std::string::npos && b != std::string::npos) << file << " is not owner__repository__name";
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string owner = file.substr(0, a), repo = file.substr(a + 2, b - a - 2), name = file.substr(b + 2);
    std::string place = repo;
    if (owner == "googlearchive" || owner == "pchen66") place = file;
    if (owner == "All4Gis") place = name.rfind("image", 0) == 0 ? "All4Gis image" : file;
    if (owner == "VGiudicelli1")
      place = name.rfind("lyon_", 0) == 0 ? "Lyon" : std::regex_match(name, uuid) ? "water tower" : "Strasbourg";
    places[place].insert(file);
  }
  return places;
}

// places.csv (file,place) of the panoramas added on 2026-11-28, read by data/places.h: place → files.
std::map<std::string, std::set<std::string>> read_places(const std::string& path) {
  std::map<std::string, std::set<std::string>> places;
  for (const auto& [file, place] : sl::data::read_places(path).place) places[place].insert(file);
  return places;
}

}  // namespace

TEST(HdriSplit, TheFirstLdrPanoramaSplitKeepsEveryPlaceInOneSplit) {
  const HdriSplit s = read_hdri_split(config("pano_ldr_split_69.json"));
  const auto split = split_of(s);
  EXPECT_EQ(split.size(), 69u);
  expect_groups_whole(split, first_split_places(split));
  // The near-duplicates MANIFEST names, explicitly.
  const std::string t = "VGiudicelli1__TSI_panoramax__", p = "proysm__Univ-Street-View__";
  expect_groups_whole(split, {{"lyon_1", {t + "lyon_1_1.jpg", t + "lyon_1_2.jpg", t + "lyon_1_3.jpg"}},
                              {"stra_3", {t + "stra_3_2.jpg", t + "stra_3_3.jpg", t + "stra_3_4.jpg"}},
                              {"street_view", {p + "Street_View_3602_1.jpg", p + "Street_View_360_1.jpg"}}});
}

TEST(HdriSplit, TheLdrPanoramaSplitKeepsEveryPlaceInOneSplit) {
  const HdriSplit s = read_hdri_split(config("pano_ldr_split.json"));
  const auto split = split_of(s);
  const HdriSplit first = read_hdri_split(config("pano_ldr_split_69.json"));
  // The first split's panoramas keep their split, so that its test figures stay comparable.
  for (const auto& [file, sp] : split_of(first)) {
    ASSERT_TRUE(split.count(file)) << file << " of pano_ldr_split_69.json is missing";
    EXPECT_EQ(split.at(file), sp) << file;
  }
  std::map<std::string, size_t> count;
  for (const auto& [f, sp] : split) ++count[sp];
  EXPECT_GE(count["train"], 450u);  // about 60 / 15 / 25 (scripts/make_pano_ldr_split.py)
  EXPECT_GE(count["val"], 100u);
  EXPECT_GE(count["test"], 180u);
  const std::string folder = shared_data("pano_ldr");
  if (!fs::is_directory(folder)) GTEST_SKIP() << "needs ../shared/data/pano_ldr (not in a fresh clone) for the folder check";
  expect_covers_exactly(s, folder, images_in(folder, {".jpg"}));
  // One place, one split: places.csv names the place of every added panorama.
  const auto places = read_places(folder + "/places.csv");
  EXPECT_EQ(places.size(), 111u);
  size_t placed = 0;
  for (const auto& [place, files] : places) placed += files.size();
  EXPECT_EQ(placed, 804u);
  expect_groups_whole(split, places);
  // The test split has enough labelled suns, streets and places to report on (data/sun_labels.h).
  const sl::data::SunLabels labels = sl::data::read_sun_labels(folder + "/sun_labels.csv");
  size_t visible = 0, street = 0, scored = 0, street_visible = 0;
  for (const auto& l : labels.rows) {
    if (split.at(l.file) != "test") continue;
    visible += l.sun == sl::data::SunVisibility::Visible;
    street += l.scene == sl::data::SceneKind::Street;
    scored += l.has_position;
    street_visible += l.scene == sl::data::SceneKind::Street && l.sun == sl::data::SunVisibility::Visible;
  }
  EXPECT_GE(visible, 60u);
  EXPECT_GE(street, 60u);
  EXPECT_GE(scored, 60u);
  EXPECT_GE(street_visible, 25u);
  std::set<std::string> test_places;
  for (const auto& [place, files] : places)
    if (split.at(*files.begin()) == "test") test_places.insert(place);
  EXPECT_GE(test_places.size(), 20u) << "the test split's suns come from too few places";
}

// scripts/place_subset_split.py (learning curves over places): a seeded half of the training places
// and its complement partition train, keep every place whole, and leave val and test as they were.
TEST(HdriSplit, APlaceSubsetAndItsComplementPartitionTrainByPlace) {
  const std::string folder = shared_data("pano_ldr");
  if (!fs::is_directory(folder)) GTEST_SKIP() << "needs ../shared/data/pano_ldr (places.csv)";
  const std::string base = "--split " + config("pano_ldr_split.json") + " --places " + folder + "/places.csv --seed 3";
  const std::string a = scratch("half_a.json"), b = scratch("half_b.json");
  const auto [code_a, text_a] = run_python_script("place_subset_split.py", base + " --out " + a);
  ASSERT_EQ(code_a, 0) << text_a;
  const auto [code_b, text_b] = run_python_script("place_subset_split.py", base + " --complement --out " + b);
  ASSERT_EQ(code_b, 0) << text_b;
  const HdriSplit full = read_hdri_split(config("pano_ldr_split.json"));
  const HdriSplit sa = read_hdri_split(a), sb = read_hdri_split(b);
  for (const char* split : {"val", "test"}) {
    EXPECT_EQ(sa.splits.at(split), full.splits.at(split)) << split;
    EXPECT_EQ(sb.splits.at(split), full.splits.at(split)) << split;
  }
  const auto& ta = sa.splits.at("train");
  const auto& tb = sb.splits.at("train");
  std::set<std::string> in_a(ta.begin(), ta.end()), in_b(tb.begin(), tb.end());
  const auto& tf = full.splits.at("train");
  EXPECT_EQ(in_a.size() + in_b.size(), tf.size());
  for (const auto& f : tf) EXPECT_NE(in_a.count(f), in_b.count(f)) << f << " must be in exactly one half";
  EXPECT_GT(in_a.size(), tf.size() / 4);
  EXPECT_GT(in_b.size(), tf.size() / 4);
  // Every place whole: places.csv's, and the first 69's (a finer grouping than the script's).
  std::map<std::string, std::string> half;
  for (const auto& f : tf) half[f] = in_a.count(f) ? "a" : "b";
  std::map<std::string, std::set<std::string>> train_places;
  for (const auto& [place, files] : read_places(folder + "/places.csv"))
    for (const auto& f : files)
      if (half.count(f)) train_places[place].insert(f);
  expect_groups_whole(half, train_places);
  std::map<std::string, std::string> first;
  for (const auto& [f, sp] : split_of(read_hdri_split(config("pano_ldr_split_69.json"))))
    if (sp == "train") first[f] = half.at(f);
  expect_groups_whole(first, first_split_places(first));
  // Bad input: one line naming the value, exit code 2, nothing written.
  const auto [bad_code, bad_text] = run_python_script("place_subset_split.py", base + " --share 0 --out " + scratch("bad.json"));
  EXPECT_EQ(bad_code, 2) << bad_text;
  EXPECT_EQ(bad_text, "error: --share 0.0: must lie in (0, 1]\n");
  EXPECT_FALSE(fs::exists(scratch("bad.json")));
}

TEST(HdriSplit, ANameInTwoSplitsIsRefusedNamingTheFileAndTheName) {
  const std::string path = scratch("twice_split.json");
  std::ofstream(path) << R"({"train": ["a.jpg", "b.jpg"], "test": ["b.jpg"]})";
  try {
    read_hdri_split(path);
    ADD_FAILURE() << "accepted a name in two splits";
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("b.jpg"), std::string::npos) << e.what();
  }
}

}  // namespace sl::test

namespace sl::test {

// "train+val" joins two splits (a final model trained on the validation places too): the names of
// each part in turn, the paths sorted as for one split; an unknown or repeated part is refused.
TEST(HdriSplit, APlusJoinsSplitsAndRefusesUnknownOrRepeatedParts) {
  const std::string dir = scratch("joined_split");
  fs::create_directories(dir);
  for (const char* n : {"a.jpg", "b.jpg", "c.jpg", "d.jpg"}) std::ofstream(dir + "/" + n) << "x";
  const std::string path = dir + "/split.json";
  std::ofstream(path) << R"({"comment": "c", "train": ["c.jpg", "a.jpg"], "val": ["b.jpg"], "test": ["d.jpg"]})";
  const HdriSplit s = read_hdri_split(path);
  EXPECT_EQ(s.split_names("train+val"), (std::vector<std::string>{"c.jpg", "a.jpg", "b.jpg"}));
  EXPECT_EQ(s.split_names("val+train"), (std::vector<std::string>{"b.jpg", "c.jpg", "a.jpg"}));
  const std::vector<std::string> joined = s.split_paths(dir, "train+val");
  std::vector<std::string> expected;
  for (const char* n : {"a.jpg", "b.jpg", "c.jpg"}) expected.push_back((fs::path(dir) / n).string());
  EXPECT_EQ(joined, expected);
  EXPECT_EQ(s.split_paths(dir, "train"), (std::vector<std::string>{expected[0], expected[2]}));
  for (const std::string bad : {"train+tset", "train+train", "train+", "+val", ""}) {
    try {
      s.split_paths(dir, bad);
      ADD_FAILURE() << "accepted split '" << bad << "'";
    } catch (const sl::Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
}

}  // namespace sl::test
