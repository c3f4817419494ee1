// util/file_kind.h: extensions ignore case and only the last one counts; folder listings are sorted
// and keep only regular files with the named extensions.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "util/error.h"
#include "util/file_kind.h"

namespace fs = std::filesystem;

namespace sl::test {
namespace {

TEST(FileKind, ExtensionIgnoresCaseAndTakesTheLastOne) {
  EXPECT_TRUE(has_extension("a/b/photo.JPG", {".jpg", ".jpeg"}));
  EXPECT_TRUE(has_extension("k.json", {".json"}));
  EXPECT_FALSE(has_extension("k.json.bak", {".json"}));
  EXPECT_FALSE(has_extension("archive.png.gz", {".png"}));
  EXPECT_FALSE(has_extension("png", {".png"}));
  EXPECT_FALSE(has_extension(".png", {".png"}));  // a hidden file named ".png" has no extension
  EXPECT_FALSE(has_extension("dir.png/file", {".png"}));
  EXPECT_FALSE(has_extension("", {".png"}));
}

TEST(FileKind, ListingIsSortedAndKeepsOnlyMatchingRegularFiles) {
  const fs::path d = fs::temp_directory_path() / ("sl_file_kind_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d / "sub.png");
  for (const char* n : {"c.png", "A.JPG", "b.jpeg", "notes.txt", "sky.hdr"}) std::ofstream(d / n) << "x";
  const auto files = files_with_extension(d.string(), {".jpg", ".jpeg", ".png"});
  ASSERT_EQ(files.size(), 3u);
  EXPECT_EQ(fs::path(files[0]).filename(), "A.JPG");
  EXPECT_EQ(fs::path(files[1]).filename(), "b.jpeg");
  EXPECT_EQ(fs::path(files[2]).filename(), "c.png");
  fs::remove_all(d);
  try {
    files_with_extension(d.string(), {".png"});
    ADD_FAILURE() << "a missing folder listed nothing instead of an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(d.string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl::test
