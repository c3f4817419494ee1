// CI replay of the fuzz corpora (issue 17): every harness of tests/fuzz/harness runs over every
// file of tests/fuzz/corpus/<target>/ in the ordinary build, so a crash fixed once stays fixed.
// A harness aborts on a broken invariant; here that fails the whole test executable loudly.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "tests/fuzz/harness/fuzz_harness.h"

namespace fs = std::filesystem;

namespace sl::test {
// Names the target in gtest's messages instead of dumping the struct's bytes.
void PrintTo(const Target& t, std::ostream* os) { *os << t.name; }
}  // namespace sl::test

namespace {

std::vector<fs::path> corpus_files(const std::string& target) {
  const fs::path dir = fs::path(STREETLIGHT_SOURCE_DIR) / "tests" / "fuzz" / "corpus" / target;
  std::vector<fs::path> files;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

class CorpusReplay : public ::testing::TestWithParam<sl::test::Target> {};

TEST_P(CorpusReplay, EveryCorpusFileIsRefusedCleanlyOrLoadsValid) {
  const sl::test::Target& t = GetParam();
  const std::vector<fs::path> files = corpus_files(t.name);
  ASSERT_GE(files.size(), 3u) << "tests/fuzz/corpus/" << t.name << " needs seeds";
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
    std::ifstream in(f, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    t.run(bytes.data(), bytes.size());  // aborts on a violated invariant
  }
}

INSTANTIATE_TEST_SUITE_P(Fuzz, CorpusReplay, ::testing::ValuesIn(sl::test::targets()),
                         [](const ::testing::TestParamInfo<sl::test::Target>& info) {
                           return std::string(info.param.name);
                         });

}  // namespace
