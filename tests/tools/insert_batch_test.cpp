// streetlight-insert --batch as a dataset augmenter : a KITTI detector must read the
// output as is — input labels carried through, inserted objects labelled with boxes that match
// them, the full calibration copied, frame ids kept — and a killed run resumes to the same set.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "data/kitti_labels.h"
#include "support/tool_fixture.h"

namespace sl::test {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const std::string kBase = " --object procedural:car --aa 1 --light-samples 4 --shadow-rays 8 --shadow-width 16"
                          " --shadow-height 8 ";

std::string read_all(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::map<std::string, std::vector<double>> calib_values(const std::string& text) {
  std::map<std::string, std::vector<double>> out;
  std::istringstream is(text);
  std::string line;
  while (std::getline(is, line)) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::istringstream vs(line.substr(colon + 1));
    double v;
    while (vs >> v) out[line.substr(0, colon)].push_back(v);
  }
  return out;
}

// KITTI frame 000008 in the KITTI layout: image_2, calib (full text, from the mmdetection3d
// JSON), label_2 (its ground-truth cars) and velodyne.
std::string kitti_fixture(const std::string& dir) {
  const std::string src = std::string(STREETLIGHT_SHARED_DATA) + "/street/kitti_000008";
  const fs::path root = fs::path(dir) / "kitti";
  for (const char* d : {"image_2", "calib", "label_2", "velodyne"}) fs::create_directories(root / d);
  fs::copy_file(src + "/000008.png", root / "image_2" / "000008.png", fs::copy_options::overwrite_existing);
  fs::copy_file(src + "/000008_velodyne.bin", root / "velodyne" / "000008.bin", fs::copy_options::overwrite_existing);
  std::ofstream(root / "calib" / "000008.txt") << sl::data::kitti_calibration_text(src + "/000008_calib.json");
  std::ifstream jf(src + "/000008_calib.json");
  const json j = json::parse(jf);
  std::ofstream lf(root / "label_2" / "000008.txt");
  for (const json& in : j["data_list"][0]["instances"]) {
    // mmdetection3d camera boxes: x y z (bottom centre) l h w ry.
    const auto& b = in["bbox"];
    const auto& d = in["bbox_3d"];
    char line[512];
    std::snprintf(line, sizeof line, "Car %.2f %d %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f\n",
                  in["truncated"].get<double>(), in["occluded"].get<int>(), in["alpha"].get<double>(),
                  b[0].get<double>(), b[1].get<double>(), b[2].get<double>(), b[3].get<double>(), d[4].get<double>(),
                  d[5].get<double>(), d[3].get<double>(), d[0].get<double>(), d[1].get<double>(), d[2].get<double>(),
                  d[6].get<double>());
    lf << line;
  }
  return root.string();
}

TEST(InsertBatch, KittiFolderKeepsIdsLabelsFullCalibrationAndUsesTheLidar) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  if (!fs::exists(std::string(STREETLIGHT_SHARED_DATA) + "/street/kitti_000008/000008.png"))
    GTEST_SKIP() << "shared KITTI frame absent";
  const std::string dir = sl::test::tool_dir("insert_batch_kitti");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const std::string in = kitti_fixture(dir), out = dir + "/aug";
  const auto r = run_tool("streetlight-insert", "--batch " + in + " --checkpoint " + ckpt + " --out " + out + kBase);
  ASSERT_EQ(r.code, 0) << r.out;
  // The frame id is kept; the whole calibration survives, value for value.
  ASSERT_TRUE(fs::exists(fs::path(out) / "image_2" / "000008.png"));
  const auto calib_in = calib_values(read_all(fs::path(in) / "calib" / "000008.txt"));
  const auto calib_out = calib_values(read_all(fs::path(out) / "calib" / "000008.txt"));
  for (const char* key : {"P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo"}) {
    ASSERT_TRUE(calib_out.count(key)) << key;
    ASSERT_EQ(calib_out.at(key).size(), calib_in.at(key).size()) << key;
    for (size_t i = 0; i < calib_in.at(key).size(); ++i)
      EXPECT_NEAR(calib_out.at(key)[i], calib_in.at(key)[i], 1e-9 * (1 + std::abs(calib_in.at(key)[i]))) << key;
  }
  // Every input label comes through (same box, truncation; occlusion never decreases), then
  // the inserted car.
  const auto labels_in = sl::data::read_kitti_labels((fs::path(in) / "label_2" / "000008.txt").string());
  const auto labels_out = sl::data::read_kitti_labels((fs::path(out) / "label_2" / "000008.txt").string());
  ASSERT_GE(labels_in.size(), 5u);
  ASSERT_EQ(labels_out.size(), labels_in.size() + 1);
  for (size_t i = 0; i < labels_in.size(); ++i) {
    EXPECT_EQ(labels_out[i].type, labels_in[i].type);
    EXPECT_NEAR(labels_out[i].truncated, labels_in[i].truncated, 1e-9);
    EXPECT_GE(labels_out[i].occluded, labels_in[i].occluded);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(labels_out[i].box2d[k], labels_in[i].box2d[k], 1e-9);
    for (int k = 0; k < 7; ++k) EXPECT_NEAR(labels_out[i].box3d[k], labels_in[i].box3d[k], 1e-9);
  }
  EXPECT_EQ(labels_out.back().type, "Car");
  std::ifstream rf(out + "/result.json");
  const json res = json::parse(rf);
  EXPECT_EQ(res["this_run"][0]["depth"], "lidar") << res.dump();
}

// --sun-from-shadows in batch mode: KITTI 000008's lidar explains its parked cars' shadows, so
// the frame's sun comes from them (result.json says so per frame).
TEST(InsertBatch, SunFromShadowsUsesEachFramesLidarShadows) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  if (!fs::exists(std::string(STREETLIGHT_SHARED_DATA) + "/street/kitti_000008/000008.png"))
    GTEST_SKIP() << "shared KITTI frame absent";
  const std::string dir = sl::test::tool_dir("insert_batch_kitti_shadows");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const std::string in = kitti_fixture(dir), out = dir + "/aug";
  const auto r = run_tool("streetlight-insert",
                          "--batch " + in + " --checkpoint " + ckpt + " --sun-from-shadows --out " + out + kBase);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("warning: --sun-from-shadows"), std::string::npos) << r.out;
  std::ifstream rf(out + "/result.json");
  const json res = json::parse(rf);
  EXPECT_EQ(res["this_run"][0]["sun_from_shadows"], true) << res.dump();
}

// Tiny photos listed nuScenes-style: one image and one intrinsics JSON per entry, ground plane.
std::string tiny_list(const std::string& dir, int n) {
  sl::test::tiny_photo(dir);
  json list = json::array();
  for (int i = 0; i < n; ++i)
    list.push_back({{"image", "photo.png"}, {"intrinsics", "intrinsics.json"}, {"id", "cam_front_" + std::to_string(i)}});
  std::ofstream(dir + "/list.json") << list.dump();
  return dir + "/list.json";
}

// Corner c of a KITTI box (h w l x y z ry; y is the bottom centre, camera y down).
std::array<double, 3> box_corner(const std::array<double, 7>& b, int c) {
  const double dx = ((c & 1) ? 0.5 : -0.5) * b[2], dz = ((c & 2) ? 0.5 : -0.5) * b[1], dy = (c & 4) ? -b[0] : 0.0;
  const double cs = std::cos(b[6]), sn = std::sin(b[6]);
  return {b[3] + cs * dx + sn * dz, b[4] + dy, b[5] - sn * dx + cs * dz};
}

TEST(InsertBatch, LabelsParseBackAndTheirBoxesMatchTheInsertedObjects) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("insert_batch_boxes");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const std::string list = tiny_list(dir, 2), out = dir + "/aug";
  const auto r = run_tool("streetlight-insert", "--batch " + list + " --checkpoint " + ckpt + " --out " + out +
                                                    " --objects-per-image 2" + kBase);
  ASSERT_EQ(r.code, 0) << r.out;
  const sl::Tensor before = sl::data::read_image(dir + "/photo.png");
  for (const std::string id : {"cam_front_0", "cam_front_1"}) {
    const auto labels = sl::data::read_kitti_labels(out + "/label_2/" + id + ".txt");
    ASSERT_EQ(labels.size(), 2u) << id;
    const auto P2 = calib_values(read_all(out + "/calib/" + id + ".txt")).at("P2");
    const sl::Tensor after = sl::data::read_image(out + "/image_2/" + id + ".png");
    const int W = int(after.size(2)), H = int(after.size(1));
    for (const auto& l : labels) {
      EXPECT_EQ(l.type, "Car");
      EXPECT_NEAR(l.box3d[4], 1.65, 0.05) << "the car stands on the ground plane 1.65 m below the camera";
      EXPECT_GT(l.box3d[0], 1.0);
      EXPECT_GT(l.box3d[2], l.box3d[1]) << "a car is longer than wide";
      // The 2D box lies inside the projection of the 3D box (the visible part of the object).
      double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
      for (int c = 0; c < 8; ++c) {
        const auto p = box_corner(l.box3d, c);
        const double u = (P2[0] * p[0] + P2[1] * p[1] + P2[2] * p[2] + P2[3]) / p[2];
        const double v = (P2[4] * p[0] + P2[5] * p[1] + P2[6] * p[2] + P2[7]) / p[2];
        u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
      }
      EXPECT_GE(l.box2d[0], std::max(0.0, u0) - 1.5);
      EXPECT_LE(l.box2d[2], std::min(double(W), u1) + 1.5);
      EXPECT_GE(l.box2d[1], std::max(0.0, v0) - 1.5);
      EXPECT_LE(l.box2d[3], std::min(double(H), v1) + 1.5);
      // The image changed inside the 2D box: the object is there.
      int changed = 0, total = 0;
      for (int y = int(l.box2d[1]); y < int(std::ceil(l.box2d[3])); ++y)
        for (int x = int(l.box2d[0]); x < int(std::ceil(l.box2d[2])); ++x, ++total)
          for (int c = 0; c < 3; ++c)
            if (std::abs(after.data<float>()[(c * H + y) * W + x] - before.data<float>()[(c * H + y) * W + x]) > 0.02f) {
              ++changed;
              break;
            }
      ASSERT_GT(total, 0);
      EXPECT_GT(changed, total / 4) << "box " << l.box2d[0] << " " << l.box2d[1] << " " << l.box2d[2] << " " << l.box2d[3];
    }
  }
}

sl::test::ToolRun run_with_env(const std::string& env, const std::string& args) {
  const std::string cmd = env + " OMP_NUM_THREADS=1 " + std::string(STREETLIGHT_BINARY_DIR) +
                          "/tools/streetlight-insert " + args + " 2>&1";
  sl::test::ToolRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  while (fgets(buf, sizeof buf, p)) r.out += buf;
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : (WIFSIGNALED(status) ? 128 + WTERMSIG(status) : -1);
  return r;
}

std::vector<std::string> names_in(const fs::path& d) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(d)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(InsertBatch, ResumeAfterAKillFinishesTheSetWithNothingDuplicatedOrMissing) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("insert_batch_resume");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const std::string list = tiny_list(dir, 5);
  const std::string args = "--batch " + list + " --checkpoint " + ckpt + kBase + " --out ";
  // An uninterrupted run, for comparison.
  ASSERT_EQ(run_tool("streetlight-insert", args + dir + "/full").code, 0);
  // Killed (SIGKILL) in the middle of the third image, its label and calib half-done.
  const auto killed = run_with_env("STREETLIGHT_INSERT_KILL_AFTER=2", args + dir + "/aug");
  EXPECT_EQ(killed.code, 128 + SIGKILL) << killed.out;
  EXPECT_EQ(names_in(dir + "/aug/image_2"), (std::vector<std::string>{"cam_front_0.png", "cam_front_1.png"}));
  EXPECT_FALSE(fs::exists(dir + "/aug/label_2/cam_front_2.txt")) << "a kill must not leave a finished-looking file";
  const std::string first = read_all(dir + "/aug/image_2/cam_front_0.png");
  // The resumed run skips the two finished images and completes the rest.
  const auto resumed = run_tool("streetlight-insert", args + dir + "/aug");
  ASSERT_EQ(resumed.code, 0) << resumed.out;
  EXPECT_NE(resumed.out.find("resuming: 2 of 5"), std::string::npos) << resumed.out;
  std::ifstream rf(dir + "/aug/result.json");
  const json res = json::parse(rf);
  EXPECT_EQ(res["this_run"].size(), 3u) << res.dump();
  for (const char* sub : {"image_2", "label_2", "calib"}) {
    const auto names = names_in(fs::path(dir) / "aug" / sub);
    EXPECT_EQ(names, names_in(fs::path(dir) / "full" / sub)) << sub;  // no leftovers, none missing
    for (const auto& n : names)
      EXPECT_EQ(read_all(fs::path(dir) / "aug" / sub / n), read_all(fs::path(dir) / "full" / sub / n)) << sub << "/" << n;
  }
  EXPECT_EQ(read_all(dir + "/aug/image_2/cam_front_0.png"), first) << "finished images are not redone";
}

TEST(InsertBatch, AnOutputFolderOfAnotherInputIsRefused) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("insert_batch_other");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  fs::create_directories(dir + "/aug");
  std::ofstream(dir + "/aug/notes.txt") << "mine";
  const auto r = run_tool("streetlight-insert", "--batch " + tiny_list(dir, 1) + " --checkpoint " + ckpt + kBase +
                                                    " --out " + dir + "/aug");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
  EXPECT_TRUE(fs::exists(dir + "/aug/notes.txt"));
}

}  // namespace

}  // namespace sl::test
