#include "data/sun_labels.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "data/augment.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "render/equirect.h"
#include "support/test_files.h"
#include "util/error.h"
#include "util/math.h"

using sl::data::LabelConfidence;
using sl::data::read_sun_labels;
using sl::data::SceneKind;
using sl::data::SunLabels;
using sl::data::SunVisibility;

namespace sl::test {

namespace {

const char* kHeader = "file,sun,u,v,confidence,scene,note\n";

std::string write_csv(const std::string& name, const std::string& body) {
  const std::string path = scratch(name);
  std::ofstream(path, std::ios::binary) << body;
  return path;
}

// The message of the sl::Error that reading `path` throws ("" when it reads).
std::string read_error(const std::string& path) {
  try {
    read_sun_labels(path);
  } catch (const sl::Error& e) {
    return e.what();
  }
  return "";
}

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / sl::kPi;
}

// The direction of the brightest texel's centre (first channel) of an H×W panorama.
glm::dvec3 brightest_direction(const sl::Tensor& pano) {
  const sl::Tensor p = pano.contiguous();
  const int h = static_cast<int>(p.size(1)), w = static_cast<int>(p.size(2));
  const float* d = p.data<float>();
  int best = 0;
  for (int i = 1; i < h * w; ++i)
    if (d[i] > d[best]) best = i;
  const auto dir = sl::render::equirect::uv_to_direction(best % w + 0.5, best / w + 0.5, w, h);
  return {dir.x, dir.y, dir.z};
}

// A dark 3-channel panorama with one bright texel under `uv` (continuous pixel coordinates).
sl::Tensor spot_panorama(int h, int w, glm::dvec2 uv) {
  sl::Tensor p = sl::Tensor::full({3, h, w}, 0.1);
  float* d = p.data<float>();
  const int col = static_cast<int>(uv.x) % w, row = std::min(static_cast<int>(uv.y), h - 1);
  for (int c = 0; c < 3; ++c) d[(c * h + row) * w + col] = 100.0f;
  return p;
}

}  // namespace

TEST(SunLabels, ParsesQuotedFieldsWithCommasQuotesAndLineBreaks) {
  const std::string path = write_csv("labels_quoted.csv", std::string(kHeader) +
                                                              "a.jpg,visible,1024,256,high,street,plain note\r\n"
                                                              "b.jpg,occluded,,,low,other,\"shadows, no disk; \"\"soft\"\"\"\n"
                                                              "\n"
                                                              "c.jpg,none,,,medium,street,\"two\nlines\"\n"
                                                              "d.jpg,occluded,10.5,20.25,medium,other,\n");
  const SunLabels l = read_sun_labels(path);
  ASSERT_EQ(l.rows.size(), 4u);
  EXPECT_EQ(l.rows[0].note, "plain note");  // CRLF stripped
  EXPECT_EQ(l.rows[1].note, "shadows, no disk; \"soft\"");
  EXPECT_FALSE(l.rows[1].has_position);
  EXPECT_EQ(l.rows[1].confidence, LabelConfidence::Low);
  EXPECT_EQ(l.rows[1].scene, SceneKind::Other);
  EXPECT_EQ(l.rows[2].note, "two\nlines");
  EXPECT_EQ(l.rows[2].sun, SunVisibility::None);
  // Line numbers are each row's first line, counting the blank line and the quoted line break.
  EXPECT_EQ(l.rows[0].line, 2);
  EXPECT_EQ(l.rows[1].line, 3);
  EXPECT_EQ(l.rows[2].line, 5);
  EXPECT_EQ(l.rows[3].line, 7);
  EXPECT_TRUE(l.rows[3].has_position);
  EXPECT_DOUBLE_EQ(l.rows[3].u, 10.5);
  EXPECT_DOUBLE_EQ(l.rows[3].v, 20.25);
  EXPECT_EQ(l.find("c.jpg"), &l.rows[2]);
  EXPECT_EQ(l.find("zzz.jpg"), nullptr);
}

TEST(SunLabels, ColumnsAreFoundByNameInAnyOrder) {
  const std::string path = write_csv("labels_order.csv", "scene,confidence,v,u,sun,file,extra\n"
                                                         "street,high,256,512,visible,a.jpg,x\n");
  const SunLabels l = read_sun_labels(path);
  ASSERT_EQ(l.rows.size(), 1u);
  EXPECT_EQ(l.rows[0].file, "a.jpg");
  EXPECT_DOUBLE_EQ(l.rows[0].u, 512);
  EXPECT_DOUBLE_EQ(l.rows[0].v, 256);
  EXPECT_TRUE(l.rows[0].note.empty());
}

TEST(SunLabels, EveryRefusalNamesTheFileAndLine) {
  struct Case {
    const char* name;
    std::string body;
    std::string expect;  // besides "<path>:<line>"
    int line;
  };
  const std::string h = kHeader;
  const std::string ok = "ok.jpg,visible,100,100,high,street,\n";
  const Case cases[] = {
      {"outside_u", h + ok + "a.jpg,visible,2049,100,high,street,\n", "outside", 3},
      {"outside_v", h + ok + "a.jpg,occluded,10,-1,high,street,\n", "outside", 3},
      {"unknown_sun", h + ok + "a.jpg,blinding,1,1,high,street,\n", "unknown sun 'blinding'", 3},
      {"unknown_conf", h + "a.jpg,none,,,sure,street,\n", "unknown confidence 'sure'", 2},
      {"unknown_scene", h + ok + "\n" + "a.jpg,none,,,low,beach,\n", "unknown scene 'beach'", 4},
      {"missing_header_column", "file,sun,u,v,scene,note\nok.jpg,none,,,street,\n", "no column 'confidence'", 1},
      {"missing_row_column", h + ok + "a.jpg,none,,,high\n", "missing column 'scene'", 3},
      {"extra_field", h + "a.jpg,none,,,high,street,note, with comma\n", "must be quoted", 2},
      {"not_a_number", h + "a.jpg,visible,12x,5,high,street,\n", "not a number", 2},
      {"half_position", h + "a.jpg,occluded,12,,high,street,\n", "both u and v", 2},
      {"visible_without_position", h + "a.jpg,visible,,,high,street,\n", "needs u and v", 2},
      {"none_with_position", h + "a.jpg,none,3,4,high,street,\n", "no sun position", 2},
      {"twice", h + ok + ok, "labelled twice", 3},
      {"unclosed_quote", h + ok + "a.jpg,none,,,high,street,\"open\nmore\n", "never closed", 3},
      {"empty", "", "empty", 1},
  };
  for (const Case& c : cases) {
    const std::string path = write_csv(std::string("labels_") + c.name + ".csv", c.body);
    const std::string msg = read_error(path);
    EXPECT_NE(msg.find(path + ":" + std::to_string(c.line)), std::string::npos) << c.name << ": " << msg;
    EXPECT_NE(msg.find(c.expect), std::string::npos) << c.name << ": " << msg;
  }
  const std::string missing = scratch("no_such_labels.csv");
  EXPECT_NE(read_error(missing).find(missing), std::string::npos);
}

TEST(SunLabels, DirectionFollowsTheEquirectConventionAtAnyImageSize) {
  const std::string path = write_csv("labels_dir.csv", std::string(kHeader) + "a.jpg,visible,1024,256,high,street,\n"
                                                                              "b.jpg,visible,1536,512,high,street,\n");
  const SunLabels l = read_sun_labels(path);
  // u = W/2 looks down −Z; v = H/4 is 45° up; u = 3W/4 is azimuth +90° (+X) on the horizon.
  const glm::dvec3 a = l.direction(l.rows[0], 2048, 1024), b = l.direction(l.rows[1], 2048, 1024);
  EXPECT_NEAR(a.x, 0.0, 1e-12);
  EXPECT_NEAR(a.y, std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(a.z, -std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(b.x, 1.0, 1e-12);
  EXPECT_NEAR(b.y, 0.0, 1e-12);
  // The label frame is 2048×1024; in a 512×256 image the pixel scales and the direction stays.
  const glm::dvec2 p = l.pixel_in(l.rows[1], 512, 256);
  EXPECT_DOUBLE_EQ(p.x, 384.0);
  EXPECT_DOUBLE_EQ(p.y, 128.0);
  EXPECT_LT(angle_deg(l.direction(l.rows[1], 512, 256), b), 1e-9);
  // And it is the one mapping's inverse: direction → (u, v) gives the scaled pixel back.
  const auto uv = sl::render::equirect::direction_to_uv(a.x, a.y, a.z, 300, 150);
  EXPECT_NEAR(uv.u, 150.0, 1e-9);
  EXPECT_NEAR(uv.v, 37.5, 1e-9);
  const std::string none = write_csv("labels_none.csv", std::string(kHeader) + "n.jpg,none,,,high,street,\n");
  const SunLabels ln = read_sun_labels(none);
  try {
    ln.direction(ln.rows[0], 64, 32);
    ADD_FAILURE() << "a label without a position has no direction";
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find(none + ":2"), std::string::npos) << e.what();
  }
}

TEST(SunLabels, RotatingOrFlippingThePanoramaMovesTheLabelsDirectionWithIt) {
  const std::string path = write_csv("labels_rot.csv", std::string(kHeader) + "a.jpg,visible,1500,400,high,street,\n");
  const SunLabels l = read_sun_labels(path);
  const int h = 128, w = 256;
  const sl::Tensor pano = spot_panorama(h, w, l.pixel_in(l.rows[0], w, h));
  const glm::dvec3 d = l.direction(l.rows[0], w, h);
  const double texel_deg = 360.0 / w;
  ASSERT_LT(angle_deg(brightest_direction(pano), d), texel_deg);  // the spot is under the label
  for (int shift : {1, 37, 128, 255}) {  // whole columns: rotate_azimuth is an exact roll
    const double delta = 2.0 * sl::kPi * shift / w;
    const sl::Tensor rotated = sl::data::rotate_azimuth(pano, delta);
    EXPECT_LT(angle_deg(brightest_direction(rotated), sl::data::rotate_direction_azimuth(d, delta)), texel_deg)
        << "shift " << shift;
    EXPECT_GT(angle_deg(brightest_direction(rotated), d), 0.5 * texel_deg) << "shift " << shift;
  }
  const sl::Tensor flipped = sl::data::flip_panorama(pano);
  EXPECT_LT(angle_deg(brightest_direction(flipped), sl::data::flip_panorama_direction(d)), texel_deg);
}

TEST(SunLabels, ACropThatContainsTheLabelledSunProjectsItInsideTheImage) {
  const std::string path = write_csv("labels_crop.csv", std::string(kHeader) + "a.jpg,visible,1500,400,high,street,\n");
  const SunLabels l = read_sun_labels(path);
  const int h = 256, w = 512;
  const glm::dvec2 uv = l.pixel_in(l.rows[0], w, h);
  const sl::Tensor pano = spot_panorama(h, w, uv);
  const glm::dvec3 sun = l.direction(l.rows[0], w, h);
  // The crop code of the real-sky benchmark (data/augment.h random_perspective_crop): wherever a
  // crop's camera projects the sun inside its image, the crop shows the bright texel there.
  sl::data::CropRanges ranges;
  ranges.width = 128;
  ranges.height = 64;
  int inside = 0;
  for (uint64_t stream = 0; stream < 48; ++stream) {
    const sl::data::RandomCrop c = sl::data::random_perspective_crop(pano, 11, stream, ranges);
    const sl::render::Projection p = c.crop.camera.project(c.crop.camera.position() + 1e3 * sun);
    if (!p.in_image) continue;
    ++inside;
    const sl::Tensor img = c.crop.image.contiguous();
    const int x = static_cast<int>(p.pixel.x), y = static_cast<int>(p.pixel.y);
    float peak = 0.0f;  // bilinear spreads the texel over the crop pixels around the projection
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = std::clamp(x + dx, 0, ranges.width - 1), yy = std::clamp(y + dy, 0, ranges.height - 1);
        peak = std::max(peak, img.data<float>()[yy * ranges.width + xx]);
      }
    EXPECT_GT(peak, 5.0f) << "stream " << stream << " pixel " << p.pixel.x << ", " << p.pixel.y;
  }
  EXPECT_GT(inside, 0) << "no random crop contained the sun";
  // A crop aimed at the label's azimuth and elevation has the sun at its centre.
  sl::data::PerspectiveCropParams aim;
  aim.yaw_rad = std::atan2(sun.x, -sun.z);
  aim.pitch_rad = std::asin(sun.y);
  aim.width = 128;
  aim.height = 64;
  const sl::data::PerspectiveCrop c = sl::data::crop_perspective(pano, aim);
  const sl::render::Projection p = c.camera.project(1e3 * sun);
  ASSERT_TRUE(p.in_image);
  EXPECT_NEAR(p.pixel.x, 64.0, 1e-6);
  EXPECT_NEAR(p.pixel.y, 32.0, 1e-6);
}

TEST(SunLabels, TheSharedPanoramaLabelsParseWithTheirManifestCounts) {
  const std::string path = shared_data("pano_ldr/sun_labels.csv");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "needs ../shared/data/pano_ldr (not in a fresh clone)";
  const SunLabels l = read_sun_labels(path);
  ASSERT_EQ(l.rows.size(), 873u);
  std::map<SunVisibility, int> sun;
  std::map<LabelConfidence, int> conf;
  std::map<SceneKind, int> scene;
  int occluded_placed = 0;
  for (const auto& r : l.rows) {
    ++sun[r.sun], ++conf[r.confidence], ++scene[r.scene];
    occluded_placed += r.sun == SunVisibility::Occluded && r.has_position;
    EXPECT_TRUE(std::filesystem::exists(shared_data("pano_ldr/" + r.file))) << r.file;
    if (r.has_position) {
      EXPECT_NEAR(glm::length(l.direction(r, 2048, 1024)), 1.0, 1e-12);
    }
  }
  // MANIFEST.md: the first 69 (31 visible, 19 occluded of which 13 placed, 19 none; 51 streets)
  // and the 804 added on 2026-11-28 (396 visible, 146 occluded of which 7 placed, 262 none; 440
  // streets).
  EXPECT_EQ(sun[SunVisibility::Visible], 31 + 396);
  EXPECT_EQ(sun[SunVisibility::Occluded], 19 + 146);
  EXPECT_EQ(sun[SunVisibility::None], 19 + 262);
  EXPECT_EQ(occluded_placed, 13 + 7);
  EXPECT_EQ(conf[LabelConfidence::High], 195);
  EXPECT_EQ(conf[LabelConfidence::Medium], 321);
  EXPECT_EQ(conf[LabelConfidence::Low], 357);
  EXPECT_EQ(scene[SceneKind::Street], 51 + 440);
  EXPECT_EQ(scene[SceneKind::Other], 18 + 364);
  // A note with commas is one field (it was quoted in the file).
  const auto* image = l.find("All4Gis__EquirectangularViewer__image.jpg");
  ASSERT_NE(image, nullptr);
  EXPECT_EQ(image->note, "sun behind thin cirrus, compact glare core; beach-chair shadows consistent");
  EXPECT_EQ(image->line, 4);
}

TEST(SunLabels, ARealLabelledPanoramaKeepsItsSunPixelUnderRotationAndFlip) {
  const std::string labels = shared_data("pano_ldr/sun_labels.csv");
  if (!std::filesystem::exists(labels)) GTEST_SKIP() << "needs ../shared/data/pano_ldr (not in a fresh clone)";
  const SunLabels l = read_sun_labels(labels);
  const auto* row = l.find("zhx1990__Photo-Sphere-Viewer__sphere_small.jpg");
  ASSERT_NE(row, nullptr);
  sl::data::ImageReadOptions ro;
  ro.transfer = sl::data::Transfer::Linear;
  ro.channels = 3;
  const sl::Tensor pano = sl::data::resize_area(sl::data::read_image(shared_data("pano_ldr/" + row->file), ro), 256, 512);
  const int h = 256, w = 512;
  const glm::dvec3 d = l.direction(*row, w, h);
  auto value_at = [&](const sl::Tensor& p, const glm::dvec3& dir) {
    const auto uv = sl::render::equirect::direction_to_uv(dir.x, dir.y, dir.z, w, h);
    float rgb[3];
    sl::data::sample_bilinear(p.contiguous().data<float>(), 3, h, w, uv.u, uv.v, rgb);
    return glm::dvec3(rgb[0], rgb[1], rgb[2]);
  };
  const glm::dvec3 at_sun = value_at(pano, d);
  EXPECT_GT(at_sun.x + at_sun.y + at_sun.z, 2.7) << "the label sits on the blown-out sun";
  const double delta = 2.0 * sl::kPi * 101 / w;
  const glm::dvec3 rotated = value_at(sl::data::rotate_azimuth(pano, delta), sl::data::rotate_direction_azimuth(d, delta));
  EXPECT_LT(glm::length(rotated - at_sun), 1e-5);
  const glm::dvec3 flipped = value_at(sl::data::flip_panorama(pano), sl::data::flip_panorama_direction(d));
  EXPECT_LT(glm::length(flipped - at_sun), 1e-5);
}

}  // namespace sl::test
