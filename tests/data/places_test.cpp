#include "data/places.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "support/test_files.h"
#include "util/error.h"

using sl::data::pick_weighted;
using sl::data::place_balanced_weights;
using sl::data::Places;
using sl::data::read_places;

namespace sl::test {

namespace {

std::string places_error(const std::string& body, const std::string& name) {
  const std::string path = scratch(name);
  write_bytes(path, body);
  try {
    read_places(path);
  } catch (const sl::Error& e) {
    return e.what();
  }
  return "";
}

std::map<std::string, double> shares(const std::vector<std::string>& places, const std::vector<double>& w) {
  std::map<std::string, double> s;
  for (size_t i = 0; i < places.size(); ++i) s[places[i]] += w[i];
  return s;
}

}  // namespace

TEST(Places, QuotedPlacesReadAndUnnamedFilesFallBackToTheirRepository) {
  const std::string path = scratch("places_ok.csv");
  write_bytes(path, "place,file\n\"Campus, Town\",a__b__1.jpg\r\nPark,c.jpg\n");
  const Places p = read_places(path);
  EXPECT_EQ(p.place.size(), 2u);
  EXPECT_EQ(p.place_of("a__b__1.jpg"), "Campus, Town");
  EXPECT_EQ(p.place_of("c.jpg"), "Park");
  EXPECT_EQ(p.place_of("owner__repo__pano.jpg"), "owner__repo");  // not in the table: its repository
  EXPECT_EQ(p.place_of("owner__repo.jpg"), "owner__repo.jpg");
  EXPECT_EQ(p.place_of("single.jpg"), "single.jpg");
}

TEST(Places, BadTablesNameTheFileAndLine) {
  EXPECT_NE(places_error("file,where\na.jpg,x\n", "p1.csv").find("p1.csv:1': the header needs the columns file and place"),
            std::string::npos);
  const std::string twice = places_error("file,place\na.jpg,x\nb.jpg,y\na.jpg,z\n", "p2.csv");
  EXPECT_NE(twice.find("p2.csv:4"), std::string::npos) << twice;
  EXPECT_NE(twice.find("'a.jpg' is named twice"), std::string::npos) << twice;
  EXPECT_NE(places_error("file,place\na.jpg,x,extra\n", "p3.csv").find("p3.csv:2': 3 fields"), std::string::npos);
  EXPECT_NE(places_error("file,place\na.jpg,\n", "p4.csv").find("p4.csv:2': empty"), std::string::npos);
  EXPECT_NE(places_error("file,place\na.jpg,\"open\n", "p5.csv").find("never closed"), std::string::npos);
  EXPECT_NE(places_error("", "p6.csv").find("p6.csv:1': the file is empty"), std::string::npos);
  try {
    read_places(scratch("no_such_places.csv"));
    FAIL() << "expected an error";
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_places.csv' cannot be opened"), std::string::npos) << e.what();
  }
}

// Three panoramas of one place and one of another: exponent 1 gives every panorama a quarter (the
// places 3:1), 0 gives each place a half, 0.5 the square roots of the sizes (√3 : 1).
TEST(Places, BalancedWeightsGiveEachPlaceItsSizeToTheExponent) {
  const std::vector<std::string> places = {"A", "B", "A", "A"};
  for (double e : {1.0, 0.5, 0.0}) {
    const auto w = place_balanced_weights(places, e);
    double sum = 0.0;
    for (double x : w) sum += x;
    EXPECT_NEAR(sum, 1.0, 1e-12) << e;
    EXPECT_DOUBLE_EQ(w[0], w[2]);  // a place's panoramas share alike
    EXPECT_DOUBLE_EQ(w[0], w[3]);
    const auto s = shares(places, w);
    EXPECT_NEAR(s.at("A") / s.at("B"), std::pow(3.0, e), 1e-12) << e;
  }
  EXPECT_DOUBLE_EQ(place_balanced_weights(places, 1.0)[1], 0.25);
  EXPECT_THROW(place_balanced_weights(places, 1.5), sl::Error);
  EXPECT_THROW(place_balanced_weights(places, -0.1), sl::Error);
  EXPECT_THROW(place_balanced_weights({}, 0.5), sl::Error);
}

TEST(Places, PickWeightedFindsTheIntervalAndNeverLeavesTheTable) {
  const std::vector<double> c = {0.25, 0.25, 0.75, 1.0};  // index 1 has weight 0
  EXPECT_EQ(pick_weighted(c, 0.0), 0u);
  EXPECT_EQ(pick_weighted(c, 0.2499), 0u);
  EXPECT_EQ(pick_weighted(c, 0.25), 2u);  // never the empty interval
  EXPECT_EQ(pick_weighted(c, 0.9999), 3u);
  EXPECT_EQ(pick_weighted({0.5, 0.9999999}, 0.99999995), 1u);  // a sum rounded under 1
}

// The shared table names a place for every panorama after the first 69, each file present.
TEST(Places, TheSharedTableCoversTheNewPanoramas) {
  const std::string path = shared_data("pano_ldr/places.csv");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "needs ../shared/data/pano_ldr (not in a fresh clone)";
  const Places p = read_places(path);
  EXPECT_EQ(p.place.size(), 804u);
  std::set<std::string> names;
  for (const auto& [f, where] : p.place) {
    EXPECT_TRUE(std::filesystem::exists(shared_data("pano_ldr/" + f))) << f;
    names.insert(where);
  }
  EXPECT_GE(names.size(), 100u);  // "from over 100 places"
}

}  // namespace sl::test
