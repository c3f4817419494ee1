// streetlight-bench sun-features (tools/bench/bench_sun_features.cpp): one row per crop with a known
// sun and one per its mirror image, in rows.csv and in every feature block, with the mirror row's
// sun mirrored; and scripts/probe_sun_features.py, scripts/ensemble_azimuth_heads.py and
// scripts/sun_half_by_split.py read what it wrote.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "data/csv.h"
#include "support/test_files.h"
#include "support/tiny_ldr_folder.h"
#include "support/tool_fixture.h"

namespace sl::test {
namespace {

namespace fs = std::filesystem;

struct Npy {
  std::vector<int64_t> shape;
  std::vector<float> values;
};

// A float32 C-order .npy (format 1.0), as the bench writes it.
Npy read_npy(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  Npy out;
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) return out;
  const size_t header_len = size_t(uint8_t(bytes[8])) | (size_t(uint8_t(bytes[9])) << 8);
  const std::string header = bytes.substr(10, header_len);
  if (header.find("'<f4'") == std::string::npos || (10 + header_len) % 64 != 0) return out;
  std::istringstream shape(header.substr(header.find("(") + 1));
  int64_t rows = 0, cols = 0;
  char comma = 0;
  shape >> rows >> comma >> cols;
  out.shape = {rows, cols};
  out.values.resize(size_t(rows * cols));
  if (bytes.size() != 10 + header_len + out.values.size() * 4) return Npy{};
  std::memcpy(out.values.data(), bytes.data() + 10 + header_len, out.values.size() * 4);
  return out;
}

std::vector<std::vector<std::string>> read_csv_rows(const fs::path& path) {
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  std::vector<std::vector<std::string>> rows;
  for (data::CsvRecord& r : data::parse_csv(text, "rows", path.string())) rows.push_back(std::move(r.fields));
  return rows;
}

TEST(BenchSunFeatures, WritesARowPerCropAndMirrorInEveryBlock) {
  if (!tool_built("streetlight-bench")) GTEST_SKIP() << "streetlight-bench not built";
  const std::string dir = tool_dir("sun_features");
  const std::string folder = tiny_ldr_folder(dir);
  const std::string ckpt = tiny_lighting_checkpoint(dir);
  const std::string glare = std::string(STREETLIGHT_SOURCE_DIR) + "/models/sun_glare.safetensors";
  if (!fs::exists(glare)) GTEST_SKIP() << glare << " is absent";
  const std::string out = dir + "/out";
  const std::string base = "sun-features --data " + folder + " --split-file " + dir + "/ldr_split.json --checkpoint " +
                           ckpt + " --sun-glare " + glare + " --mobilenet none --crops 2";
  const ToolRun r = run_tool("streetlight-bench", base + " --split test --out " + out);
  ASSERT_EQ(r.code, 0) << r.out;
  // Test split: a (visible) and b (occluded with a position) have a known sun: 2 crops each, and
  // their mirror images.
  const auto rows = read_csv_rows(fs::path(out) / "rows.csv");
  ASSERT_EQ(rows.size(), 1u + 8u);
  ASSERT_EQ(rows[0][4], "flip");
  for (size_t k = 1; k < rows.size(); k += 2) {
    ASSERT_EQ(rows[k].size(), 14u);
    EXPECT_EQ(rows[k][4], "0");
    EXPECT_EQ(rows[k + 1][4], "1");
    EXPECT_EQ(rows[k][1], rows[k + 1][1]);
    EXPECT_NEAR(std::stod(rows[k][5]), -std::stod(rows[k + 1][5]), 1e-6);  // the sun mirrored: x → −x
    EXPECT_EQ(rows[k][6], rows[k + 1][6]);
    EXPECT_EQ(rows[k][7], rows[k + 1][7]);
    EXPECT_NEAR(std::stod(rows[k][11]), -std::stod(rows[k + 1][11]), 1e-6);
  }
  const Npy stats = read_npy(fs::path(out) / "statistics.npy");
  ASSERT_EQ(stats.shape, (std::vector<int64_t>{8, 102}));
  // The mirror image's statistics: the right-minus-left brightness (index 96) negated.
  for (int k = 0; k < 8; k += 2) EXPECT_NEAR(stats.values[k * 102 + 96], -stats.values[(k + 1) * 102 + 96], 1e-5);
  for (const char* block : {"backbone", "glare_azimuth", "glare_azimuth_p"}) {
    const Npy b = read_npy(fs::path(out) / (std::string(block) + ".npy"));
    ASSERT_EQ(b.shape.size(), 2u) << block;
    EXPECT_EQ(b.shape[0], 8) << block;
    for (float v : b.values) ASSERT_TRUE(std::isfinite(v)) << block;
  }
  const Npy p = read_npy(fs::path(out) / "glare_azimuth_p.npy");
  for (int k = 0; k < 8; ++k) {
    double sum = 0;
    for (int64_t j = 0; j < p.shape[1]; ++j) sum += p.values[k * p.shape[1] + j];
    EXPECT_NEAR(sum, 1.0, 1e-5);
  }
  EXPECT_FALSE(fs::exists(fs::path(out) / "mobilenet.npy"));
  // Bad input: one line naming the value.
  const ToolRun bad = run_tool("streetlight-bench", base + " --split all --out " + dir + "/bad");
  expect_clean_error(bad, dir + "/bad", "all");
  // The probe script fits on the train rows and reads the test rows.
  const ToolRun train = run_tool("streetlight-bench", base + " --split train --out " + dir + "/train");
  ASSERT_EQ(train.code, 0) << train.out;
  const std::string script = std::string(STREETLIGHT_SOURCE_DIR) + "/scripts/probe_sun_features.py";
  // Debian's interpreter, which scripts/install_deps.sh gives numpy; else the first on PATH.
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  FILE* pipe = popen((python + " " + script + " --train " + dir + "/train --val " + out + " --blocks statistics --lambdas 10 " +
                      "--json " + dir + "/probe.json 2>&1")
                         .c_str(),
                     "r");
  ASSERT_NE(pipe, nullptr);
  std::string text;
  char buf[512];
  while (fgets(buf, sizeof buf, pipe)) text += buf;
  const int status = pclose(pipe);
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0 && text.find("No module named 'numpy'") != std::string::npos)
    GTEST_SKIP() << "numpy is absent";
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << text;
  EXPECT_NE(text.find("| statistics (102) | 10 |"), std::string::npos) << text;
  EXPECT_TRUE(fs::exists(dir + "/probe.json"));
  // The ensemble script: the mean of two identical heads answers as each does; folders of other crops
  // are a one-line error with exit code 2.
  auto run_script = [&](const std::string& args) { return run_python_script("ensemble_azimuth_heads.py", args); };
  const auto [code, table] = run_script("a=" + out + " b=" + out);
  ASSERT_EQ(code, 0) << table;
  auto cell = [&](const std::string& row) {
    const size_t at = table.find("| " + row + " | ");
    if (at == std::string::npos) return std::string("missing");
    const size_t begin = at + row.size() + 5;
    return table.substr(begin, table.find(" |", begin) - begin);
  };
  EXPECT_NE(cell("a"), "missing") << table;
  EXPECT_EQ(cell("a"), cell("b")) << table;
  EXPECT_EQ(cell("mean of a + b"), cell("a")) << table;
  const auto [bad_code, bad_text] = run_script("a=" + out + " b=" + dir + "/train");
  EXPECT_EQ(bad_code, 2) << bad_text;
  EXPECT_EQ(bad_text.rfind("error: ", 0), 0u) << bad_text;
  EXPECT_EQ(std::count(bad_text.begin(), bad_text.end(), '\n'), 1) << bad_text;
  // The split script counts every crop once (the mirror rows left out), and a folder without rows is
  // one line with exit code 2 and nothing else printed.
  auto run_split = [&](const std::string& args) { return run_python_script("sun_half_by_split.py", args); };
  const auto [split_code, split_table] = run_split("mine=" + out);
  ASSERT_EQ(split_code, 0) << split_table;
  EXPECT_NE(split_table.find("| mine | " + std::to_string((rows.size() - 1) / 2) + " | "), std::string::npos)
      << split_table;
  const auto [none_code, none_text] = run_split("mine=" + out + " other=" + dir + "/nowhere");
  EXPECT_EQ(none_code, 2) << none_text;
  EXPECT_EQ(none_text.rfind("error: ", 0), 0u) << none_text;
  EXPECT_EQ(std::count(none_text.begin(), none_text.end(), '\n'), 1) << none_text;
}

}  // namespace
}  // namespace sl::test
