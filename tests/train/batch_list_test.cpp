// The --batch list of streetlight-insert (train/batch_list.h): paths resolved against the list's
// folder, the optional "fov" of a photo without intrinsics, and one error naming the list.
#include "train/batch_list.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "support/test_files.h"
#include "util/error.h"

namespace sl::test {
namespace {

std::string write_list(const std::string& name, const std::string& text) {
  const std::string path = scratch(name);
  std::ofstream(path) << text;
  return path;
}

TEST(BatchList, AFieldOfViewStandsInForIntrinsics) {
  const std::string path = write_list("batch_fov.json", R"([{"image": "a.jpg", "fov": 65.5}, {"image": "/abs/b.jpg",
      "intrinsics": "k.json", "id": "b"}])");
  const auto list = train::read_batch_list(path);
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].sources.fov_deg, 65.5);
  EXPECT_EQ(list[0].sources.image, scratch("a.jpg"));
  EXPECT_EQ(list[0].sources.intrinsics, "");
  EXPECT_EQ(list[0].id, "000000");
  EXPECT_EQ(list[1].sources.fov_deg, 0.0) << "absent: not given (the EXIF focal length, else an error)";
  EXPECT_EQ(list[1].sources.image, "/abs/b.jpg");
  EXPECT_EQ(list[1].sources.intrinsics, scratch("k.json"));
}

TEST(BatchList, ABadFieldOfViewIsOneErrorNamingTheList) {
  for (const char* fov : {"\"60\"", "0", "180", "-1", "1e999"}) {
    SCOPED_TRACE(fov);
    const std::string path = write_list("batch_bad_fov.json", std::string(R"([{"image": "a.jpg", "fov": )") + fov + "}]");
    try {
      train::read_batch_list(path);
      ADD_FAILURE() << "accepted fov " << fov;
    } catch (const sl::Error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(path), std::string::npos) << m;
      EXPECT_NE(m.find("fov"), std::string::npos) << m;
    } catch (const std::exception& e) {
      // nlohmann rejects 1e999 as out of range while parsing: still one error naming the list.
      ADD_FAILURE() << "not an sl::Error: " << e.what();
    }
  }
}

}  // namespace
}  // namespace sl::test
