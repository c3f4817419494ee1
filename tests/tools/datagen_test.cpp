// streetlight-datagen --reuse (data/sample_reuse.h): linking an earlier render's samples gives the
// bytes a fresh render writes, renders only what the source lacks, and refuses another config.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <nlohmann/json.hpp>

#include "support/tool_fixture.h"

namespace sl::test {

namespace {

namespace fs = std::filesystem;

std::string bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Every file under a and b, compared byte for byte; returns the first difference, or "".
std::string first_difference(const fs::path& a, const fs::path& b) {
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    ++files;
    const fs::path rel = fs::relative(e.path(), a);
    if (!fs::exists(b / rel)) return rel.string() + " is missing in " + b.string();
    if (bytes(e.path()) != bytes(b / rel)) return rel.string() + " differs";
  }
  for (const auto& e : fs::recursive_directory_iterator(b))
    if (e.is_regular_file() && !fs::exists(a / fs::relative(e.path(), b)))
      return fs::relative(e.path(), b).string() + " is only in " + b.string();
  return files == 0 ? "no files in " + a.string() : "";
}

class DatagenReuse : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!tool_built("streetlight-datagen")) GTEST_SKIP() << "streetlight-datagen is not built";
    // One folder per test: ctest runs the tests of this fixture in parallel processes.
    dir_ = tool_dir(std::string("datagen_reuse_") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    config_ = (dir_ / "tiny.json").string();
    std::ofstream(config_) << R"({"seed": 3,
      "render": {"spp": 2, "max_depth": 2, "environment_width": 32, "target_noise": 0},
      "panorama": {"width": 32, "height": 16}, "views": {"count": 1, "width": 32, "height": 16},
      "sky": {"width": 32, "height": 8}, "insertion": {"min_visible_pixels": 4, "coverage_samples": 2}})";
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  // streetlight-datagen on the tiny config, `samples` samples into dir_/out, plus `extra` flags.
  ToolRun datagen(int samples, const std::string& out, const std::string& extra = "") {
    return run_tool("streetlight-datagen", "--config " + config_ + " --samples " + std::to_string(samples) + " --out " +
                                               (dir_ / out).string() + " --json " + extra);
  }
  static nlohmann::json summary(const ToolRun& r) {
    const auto brace = r.out.rfind("\n{");
    return nlohmann::json::parse(brace == std::string::npos ? r.out : r.out.substr(brace + 1));
  }
  fs::path dir_;
  std::string config_;
};

}  // namespace

TEST_F(DatagenReuse, LinkedSamplesAreTheBytesOfAFreshRenderWithTheirOwnSplit) {
  ASSERT_EQ(datagen(3, "source").code, 0);
  const ToolRun fresh = datagen(2, "fresh");
  ASSERT_EQ(fresh.code, 0) << fresh.out;
  const ToolRun linked = datagen(2, "linked", "--reuse " + (dir_ / "source").string());
  ASSERT_EQ(linked.code, 0) << linked.out;
  EXPECT_EQ(summary(linked)["rendered"], 0);
  EXPECT_EQ(summary(linked)["reused"], 2);
  // Samples, index.json (a split over two ids, not the source's three) and all: the same bytes.
  EXPECT_EQ(first_difference(dir_ / "fresh", dir_ / "linked"), "");
  EXPECT_NE(bytes(dir_ / "source" / "index.json"), bytes(dir_ / "linked" / "index.json"));
  // Linked, not copied: the file is the source's (same file system here).
  struct stat a {}, b {};
  ASSERT_EQ(::stat((dir_ / "source/samples/000001/meta.json").c_str(), &a), 0);
  ASSERT_EQ(::stat((dir_ / "linked/samples/000001/meta.json").c_str(), &b), 0);
  EXPECT_EQ(a.st_ino, b.st_ino);
}

TEST_F(DatagenReuse, RendersOnlyTheSamplesTheSourceLacks) {
  ASSERT_EQ(datagen(2, "source").code, 0);
  const ToolRun more = datagen(3, "more", "--reuse " + (dir_ / "source").string());
  ASSERT_EQ(more.code, 0) << more.out;
  EXPECT_EQ(summary(more)["reused"], 2);
  EXPECT_EQ(summary(more)["rendered"], 1);
  ASSERT_EQ(datagen(3, "fresh").code, 0);
  EXPECT_EQ(first_difference(dir_ / "fresh", dir_ / "more"), "");
  // An incomplete source sample (no meta.json, as a killed render could not leave one, but a
  // hand-edited folder can) is rendered, not linked.
  fs::remove(dir_ / "source/samples/000000/meta.json");
  const ToolRun again = datagen(2, "again", "--reuse " + (dir_ / "source").string());
  ASSERT_EQ(again.code, 0) << again.out;
  EXPECT_EQ(summary(again)["reused"], 1);
  EXPECT_EQ(summary(again)["rendered"], 1);
  for (const char* id : {"000000", "000001"})
    EXPECT_EQ(first_difference(dir_ / "again/samples" / id, dir_ / "fresh/samples" / id), "") << id;
}

TEST_F(DatagenReuse, AnotherConfigOrAMissingSourceIsBadInputWithNoOutput) {
  ASSERT_EQ(datagen(1, "source").code, 0);
  const std::string src = " --reuse " + (dir_ / "source").string();
  const ToolRun other = datagen(1, "other", "--set render.spp=3" + src);
  expect_clean_error(other, (dir_ / "other").string(), "'render.spp' is 2 there and 3 here");
  const ToolRun missing = datagen(1, "missing", "--reuse " + (dir_ / "nowhere").string());
  expect_clean_error(missing, (dir_ / "missing").string(), "nowhere/index.json");
  const ToolRun itself = datagen(1, "source", src);
  EXPECT_EQ(itself.code, 2) << itself.out;
  EXPECT_NE(itself.out.find("is the --out folder itself"), std::string::npos) << itself.out;
}

TEST_F(DatagenReuse, APathSpelledAnotherWayNamesTheSameConfigAndLinkedObjectsAreCounted) {
  // The object file, spelled absolute for the source and relative for the second render (the
  // tools run in this test's working directory, so both name the same file).
  const fs::path box = dir_ / "box.glb", other = dir_ / "other.glb";
  fs::copy_file(fs::path(STREETLIGHT_SOURCE_DIR) / "tests/fuzz/corpus/gltf/w_box.glb", box);
  fs::copy_file(box, other);
  const std::string relative = fs::relative(box, fs::current_path()).string();
  ASSERT_NE(relative, box.string());
  const ToolRun source = datagen(2, "source", "--set insertion.object=" + box.string());
  ASSERT_EQ(source.code, 0) << source.out;
  const ToolRun linked = datagen(2, "linked", "--set insertion.object=" + relative + " --reuse " + (dir_ / "source").string());
  ASSERT_EQ(linked.code, 0) << linked.out;
  EXPECT_EQ(summary(linked)["reused"], 2);
  EXPECT_EQ(summary(linked)["rendered"], 0);
  // with_object counts the linked samples as a render counts its own.
  EXPECT_EQ(summary(linked)["with_object"], summary(source)["with_object"]);
  EXPECT_GT(summary(source)["with_object"].get<int>(), 0);
  // A copy of the file is another file: its bytes could change, so it is another config.
  const ToolRun copy = datagen(2, "copy", "--set insertion.object=" + other.string() + " --reuse " + (dir_ / "source").string());
  expect_clean_error(copy, (dir_ / "copy").string(), "'insertion.object'");
}

}  // namespace sl::test
