// The synthetic street generator: geometry consistency between views, the true sun, the
// insertion pair, determinism and atomic sample folders.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "data/image_io.h"
#include "data/object_placement.h"
#include "data/procedural_car.h"
#include "data/street_dataset.h"
#include "data/street_generator.h"
#include "data/street_scene.h"
#include "data/sun_extraction.h"
#include "render/equirect.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "support/street_fixture.h"
#include "util/math.h"

using sl::data::build_street_scene;
using sl::data::extract_sun;
using sl::data::FootprintXZ;
using sl::data::generate_street_sample;
using sl::data::GeneratedSample;
using sl::data::make_procedural_car;
using sl::data::read_image;
using sl::data::split_ids;
using sl::data::street_generator_config;
using sl::data::StreetDataset;
using sl::data::StreetGeneratorConfig;
using sl::data::StreetSample;
using sl::data::StreetScene;
using sl::data::StreetSceneConfig;
using sl::data::StreetView;
using sl::data::SunEstimate;
using sl::render::Bounds3;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::EnvironmentMap;
using sl::render::intrinsics_from_fov;
using sl::render::Mesh;
using sl::render::PathTracer;
using sl::render::PathTracerImage;
using sl::render::PathTracerOptions;
using sl::render::placed_mesh;
using sl::render::Placement;
using sl::render::Projection;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::test {
namespace {

namespace fs = std::filesystem;

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)) * 180.0 / kPi;
}

TEST(StreetScene, IsValidSmallAndDeterministic) {
  const StreetScene a = build_street_scene({}, 3), b = build_street_scene({}, 3), c = build_street_scene({}, 4);
  EXPECT_NO_THROW(a.mesh.validate());
  EXPECT_GT(a.mesh.triangle_count(), 100u);
  EXPECT_LT(a.mesh.triangle_count(), 6000u);
  EXPECT_EQ(a.mesh.positions, b.mesh.positions);
  EXPECT_NE(a.mesh.positions.size() == c.mesh.positions.size() && a.mesh.positions == c.mesh.positions, true);
  // Buildings stand off the road on both sides.
  int left = 0, right = 0;
  for (const FootprintXZ& o : a.obstacles)
    if (o.kind == "building") {
      EXPECT_TRUE(o.x1 < -a.road_half_width_m || o.x0 > a.road_half_width_m);
      (o.x0 > 0 ? right : left)++;
    }
  EXPECT_GT(left, 0);
  EXPECT_GT(right, 0);
}

TEST(StreetScene, ManySeedsAndExtremeRangesBuildValidScenes) {
  StreetSceneConfig narrow;
  narrow.building_frontage_min_m = narrow.building_frontage_max_m = 2.0;
  narrow.building_depth_min_m = narrow.building_depth_max_m = 2.0;
  narrow.building_gap_probability = 0.9;
  narrow.parked_cars_max = 64;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    EXPECT_NO_THROW(build_street_scene({}, seed).mesh.validate()) << seed;
    EXPECT_NO_THROW(build_street_scene(narrow, seed).mesh.validate()) << seed;
  }
}

TEST(StreetScene, RejectsInvertedRanges) {
  StreetSceneConfig c;
  c.building_height_min_m = 10.0;
  c.building_height_max_m = 5.0;
  EXPECT_THROW(build_street_scene(c, 0), Error);
}

TEST(ProceduralCar, HasCarDimensionsOnTheGround) {
  const Mesh car = make_procedural_car();
  const Bounds3 b = car.bounds();
  EXPECT_NEAR(b.lo.y, 0.0, 1e-5);
  EXPECT_NEAR(b.hi.y, 1.5, 1e-5);
  EXPECT_NEAR(b.extent().x, 4.5, 0.15);  // bumpers stick out a few cm
  EXPECT_NEAR(b.extent().z, 1.8, 0.05);
  EXPECT_LT(car.triangle_count(), 1000u);
}

TEST(StreetGenerator, DepthReprojectsBetweenViews) {
  const std::string dir = test::tiny_dataset();
  const StreetDataset all(dir, "train");
  ASSERT_GT(all.size(), 0u);
  int compared = 0, agreeing = 0;
  for (size_t i = 0; i < all.size(); ++i) {
    const StreetSample s = all.load(i);
    ASSERT_GE(s.views.size(), 2u);
    const StreetView &v0 = s.views[0], &v1 = s.views[1];
    const int W0 = v0.camera.intrinsics().width, H0 = v0.camera.intrinsics().height;
    const int W1 = v1.camera.intrinsics().width;
    const float* d0 = v0.depth.data<float>();
    const float* d1 = v1.depth.data<float>();
    for (int r = 0; r < H0; ++r)
      for (int c = 0; c < W0; ++c) {
        const float z0 = d0[r * W0 + c];
        if (!(z0 > 0.0f)) continue;
        const glm::dvec3 p = v0.camera.unproject(c + 0.5, r + 0.5, z0);
        const Projection pr = v1.camera.project(p);
        if (!pr.in_image) continue;
        const int c1 = static_cast<int>(pr.pixel.x), r1 = static_cast<int>(pr.pixel.y);
        const float z1 = d1[r1 * W1 + c1];
        if (!(z1 > 0.0f)) continue;
        ++compared;
        // Nearest-pixel lookup: a pixel's footprint at depth z spans about z / fx metres.
        const double tol = 0.03 * pr.depth + 2.0 * pr.depth / v1.camera.intrinsics().fx;
        agreeing += std::abs(z1 - pr.depth) < tol;
      }
  }
  ASSERT_GT(compared, 200);
  // Occlusion boundaries and surfaces seen by one view only are the exceptions.
  EXPECT_GT(static_cast<double>(agreeing) / compared, 0.85) << agreeing << " of " << compared;
}

TEST(StreetGenerator, TrueSunMatchesThePeakOfTheSkyAndThePanorama) {
  nlohmann::json t = test::tiny_generator_tree(1);
  t["sky"]["elevation_min_deg"] = 55.0;  // above the (low) buildings, so the panorama sees it
  t["sky"]["elevation_max_deg"] = 80.0;
  t["sky"]["cloud_probability"] = 0.0;
  t["sky"]["width"] = 256;
  t["sky"]["height"] = 64;
  t["render"]["environment_width"] = 256;
  t["panorama"] = {{"width", 128}, {"height", 64}};
  t["scene"]["building_height_m"] = {4.0, 6.0};
  t["insertion"]["enabled"] = false;
  t["views"]["count"] = 1;
  const StreetGeneratorConfig c = street_generator_config(t);
  const std::string out = test::scratch("sun_sample");
  fs::create_directories(out);
  const GeneratedSample g = generate_street_sample(c, 0, out);
  const fs::path d = fs::path(out) / g.id;
  std::ifstream f(d / "meta.json");
  const nlohmann::json meta = nlohmann::json::parse(f);
  const glm::dvec3 sun(meta["sun_direction"][0], meta["sun_direction"][1], meta["sun_direction"][2]);
  const SunEstimate from_sky = extract_sun(read_image((d / "sky_hdr.exr").string()));
  const SunEstimate from_pano = extract_sun(read_image((d / "pano_hdr.exr").string()));
  ASSERT_TRUE(from_sky.found && from_pano.found);
  EXPECT_LT(angle_deg(sun, from_sky.direction), 1.0);
  EXPECT_LT(angle_deg(sun, from_pano.direction), 2.0);
}

// The exact version of "with and without the object agree outside its shadow and footprint".
// The path tracer keys every random number by (pixel, sample, bounce, use), never by the
// scene, so a path that never meets the object draws the same numbers and the same result in
// both scenes. With direct lighting only (max_depth 1) and a sky that is black except for the
// sun, a path meets the object only if its camera ray or its shadow ray towards the sun does:
// a BRDF-sampled ray that hits the object instead of the black sky contributes 0 either way.
// So the images must be bitwise equal outside (coverage ∪ sun-shadow), dilated by the sun
// texel's bilinear reach and pixel jitter. (With indirect light, any pixel whose bounce paths
// meet the object may differ too; InsertionPairIsSameSeedRender checks the generated pairs.)
TEST(StreetGenerator, InsertionPairIsBitwiseEqualOutsideObjectAndShadow) {
  StreetSceneConfig sc;
  sc.parked_cars_max = 0;
  const StreetScene scene = build_street_scene(sc, 11);
  const int eh = 32, ew = 64;
  Tensor env_t = Tensor::zeros({3, eh, ew});
  const int sun_row = 8, sun_col = 40;  // elevation ~39°, azimuth ~45°
  for (int ch = 0; ch < 3; ++ch) env_t.data<float>()[(ch * eh + sun_row) * ew + sun_col] = 5000.0f;
  const EnvironmentMap env(env_t);
  const Mesh car = make_procedural_car();
  Placement pl;
  pl.z_m = -9.0;
  pl.x_m = 0.5;
  pl.yaw_deg = 80.0;
  const Mesh placed = placed_mesh(car, pl);
  Mesh with = scene.mesh;
  with.append(placed);
  const PathTracer without_t(scene.mesh, env), with_t(with, env), object_t(placed, env);
  const Camera cam(intrinsics_from_fov(70.0 * kDegToRad, 64, 32), rotation_from_yaw_pitch_roll(0, -0.1, 0),
                   {0.0, 1.6, 0.0});
  PathTracerOptions o;
  o.spp = 4;
  o.max_depth = 1;
  o.seed = 1234;
  const PathTracerImage a = without_t.render(cam, o), b = with_t.render(cam, o);

  // Region the object can touch: its coverage, and points whose shadow rays towards any
  // direction the sun's texel can be sampled or looked up in (its 3×3 neighbourhood) hit it.
  const int W = 64, H = 32;
  std::vector<uint8_t> region(W * H, 0);
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      for (int sy = 0; sy < 3 && !region[r * W + c]; ++sy)
        for (int sx = 0; sx < 3; ++sx) {
          const CameraRay ray = cam.ray(c + (sx + 0.5) / 3, r + (sy + 0.5) / 3);
          if (object_t.first_hit(glm::vec3(ray.origin), glm::vec3(ray.direction)).hit) region[r * W + c] = 1;
        }
      const float z = a.depth.data<float>()[r * W + c];
      if (region[r * W + c] || !(z > 0.0f)) continue;
      const glm::dvec3 p = cam.unproject(c + 0.5, r + 0.5, z);
      const glm::dvec3 n(a.normal.data<float>()[r * W + c], a.normal.data<float>()[H * W + r * W + c],
                         a.normal.data<float>()[2 * H * W + r * W + c]);
      for (int k = 0; k < 49 && !region[r * W + c]; ++k) {
        const double u = sun_col - 1.0 + 3.0 * (k % 7 + 0.5) / 7, v = sun_row - 1.0 + 3.0 * (k / 7 + 0.5) / 7;
        const render::equirect::Dir d = render::equirect::uv_to_direction(u, v, ew, eh);
        if (object_t.first_hit(glm::vec3(p + 1e-3 * n), glm::vec3(d.x, d.y, d.z)).hit) region[r * W + c] = 1;
      }
    }
  // Dilate by 2 pixels for sub-pixel jitter of the camera rays.
  std::vector<uint8_t> grown = region;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c)
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) {
          const int rr = r + dy, cc = c + dx;
          if (rr >= 0 && rr < H && cc >= 0 && cc < W && region[rr * W + cc]) grown[r * W + c] = 1;
        }
  int outside = 0, differing_inside = 0, inside = 0;
  for (int i = 0; i < W * H; ++i) {
    bool same = true;
    for (int ch = 0; ch < 3; ++ch) same = same && a.radiance.data<float>()[ch * W * H + i] == b.radiance.data<float>()[ch * W * H + i];
    if (grown[i]) {
      ++inside;
      differing_inside += !same;
    } else {
      ++outside;
      EXPECT_TRUE(same) << "pixel " << i % W << ", " << i / W << " differs outside the object and its shadow";
    }
  }
  EXPECT_GT(outside, W * H / 2);       // the test constrains most of the image
  EXPECT_GT(differing_inside, 10);     // and the object really changes the image
  EXPECT_LT(inside, W * H / 2);
}

TEST(StreetGenerator, InsertionPairIsSameSeedRender) {
  const std::string dir = test::tiny_dataset();
  for (const std::string split : {"train", "val", "test"}) {
    const StreetDataset ds(dir, split);
    for (size_t i = 0; i < ds.size(); ++i) {
      const StreetSample s = ds.load(i);
      if (!s.has_insertion) continue;
      const float* a = s.insert_without_object_hdr.data<float>();
      const float* b = s.insert_with_object_hdr.data<float>();
      const float* m = s.insert_object_mask.data<float>();
      const int64_t n = s.insert_object_mask.numel();
      int64_t equal = 0, covered_differ = 0, covered = 0;
      for (int64_t p = 0; p < n; ++p) {
        equal += a[p] == b[p] && a[n + p] == b[n + p] && a[2 * n + p] == b[2 * n + p];
        if (m[p] > 0.5f) ++covered, covered_differ += a[p] != b[p];
      }
      EXPECT_GT(static_cast<double>(equal) / n, 0.3) << s.id;  // same streams: most pixels identical
      EXPECT_GT(covered, 0) << s.id;
      EXPECT_GT(covered_differ, covered / 2) << s.id;
      // The 2D box holds the mask; the 3D box's centre projects inside the image.
      EXPECT_LE(s.box2d[0], s.box2d[2]);
      EXPECT_LE(s.box2d[1], s.box2d[3]);
      EXPECT_GT(s.box3d[5], 0.0);
      EXPECT_NEAR(s.box3d[2], 4.5, 0.5);
    }
  }
}

// insertion.spp renders the pair again, cleaner, with the same streams for both images; and
// insertion.light_probe writes the light at the object, which the loader returns.
TEST(StreetGenerator, CleanInsertionPairAndLightProbeAtTheObject) {
  nlohmann::json t = test::tiny_generator_tree(3);
  t["insertion"]["spp"] = 16;
  t["insertion"]["light_probe"] = true;
  t["splits"] = {{"train", 0.0}, {"val", 0.0}};
  const StreetGeneratorConfig c = street_generator_config(t);
  const std::string out = test::scratch("clean_pair");
  fs::remove_all(out);
  fs::create_directories(fs::path(out) / "samples");
  std::vector<std::string> ids;
  for (int64_t i = 0; i < c.samples; ++i) ids.push_back(generate_street_sample(c, i, out + "/samples").id);
  write_dataset_index(out, c, split_ids(ids, c.seed, c.train_fraction, c.val_fraction));
  const StreetDataset ds(out, "test");
  int checked = 0;
  for (size_t i = 0; i < ds.size(); ++i) {
    const StreetSample s = ds.load(i);
    if (!s.has_insertion) continue;
    ++checked;
    std::ifstream mf(fs::path(out) / "samples" / s.id / "meta.json");
    const nlohmann::json meta = nlohmann::json::parse(mf);
    EXPECT_EQ(meta["render"]["images"]["insert_with_object"]["spp"].get<int>(), 16) << s.id;
    EXPECT_EQ(meta["render"]["images"]["insert_without_object"]["spp"].get<int>(), 16) << s.id;
    // The pair: same streams (most pixels bitwise equal), a new render (not view 0's 2 spp),
    // and unbiased (its mean agrees with view 0's).
    const int64_t n = s.insert_object_mask.numel();
    const float *a = s.insert_without_object_hdr.data<float>(), *b = s.insert_with_object_hdr.data<float>();
    const float* v0 = s.views[0].hdr.data<float>();
    int64_t equal = 0, differs_from_view0 = 0;
    double mean_clean = 0, mean_view0 = 0;
    for (int64_t p = 0; p < 3 * n; ++p) {
      equal += a[p] == b[p];
      differs_from_view0 += a[p] != v0[p];
      mean_clean += a[p], mean_view0 += v0[p];
    }
    EXPECT_GT(static_cast<double>(equal) / (3 * n), 0.3) << s.id;
    EXPECT_GT(differs_from_view0, n) << s.id;
    EXPECT_NEAR(mean_clean / mean_view0, 1.0, 0.15) << s.id;
    // The probe: a finite panorama of the panorama's size, taken at the object's centre.
    ASSERT_TRUE(s.insert_light_probe_hdr.defined()) << s.id;
    EXPECT_EQ(s.insert_light_probe_hdr.size(1), s.pano_hdr.size(1));
    EXPECT_EQ(s.insert_light_probe_hdr.size(2), s.pano_hdr.size(2));
    const float* q = s.insert_light_probe_hdr.data<float>();
    for (int64_t p = 0; p < s.insert_light_probe_hdr.numel(); ++p) ASSERT_TRUE(std::isfinite(q[p]) && q[p] >= 0.0f);
    EXPECT_NEAR(s.light_probe_position.x, s.object_x, 1.0) << s.id;
    EXPECT_NEAR(s.light_probe_position.z, s.object_z, 1.0) << s.id;
    EXPECT_GT(s.light_probe_position.y, 0.2) << s.id;
    EXPECT_LT(s.light_probe_position.y, 2.0) << s.id;
  }
  EXPECT_GT(checked, 0);
}

std::string file_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

TEST(StreetGenerator, SameSeedWritesSameFilesWithAnyThreadCount) {
  const StreetGeneratorConfig c = street_generator_config(test::tiny_generator_tree(1));
  const std::string a = test::scratch("det_a"), b = test::scratch("det_b");
  fs::create_directories(a);
  fs::create_directories(b);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  generate_street_sample(c, 0, a);
  omp_set_num_threads(2);
  generate_street_sample(c, 0, b);
  omp_set_num_threads(threads);
  int files = 0;
  for (const auto& e : fs::directory_iterator(fs::path(a) / "000000")) {
    ++files;
    EXPECT_EQ(file_bytes(e.path()), file_bytes(fs::path(b) / "000000" / e.path().filename()))
        << e.path().filename();
  }
  EXPECT_GE(files, 14);
}

TEST(StreetGenerator, FailedSampleLeavesNoFolder) {
  nlohmann::json t = test::tiny_generator_tree(1);
  const std::string hdris = test::scratch("bad_hdris");
  fs::create_directories(hdris);
  test::write_bytes(hdris + "/broken.hdr", "#?RADIANCE\nnot really\n");
  t["sky"]["hdri_folder"] = hdris;
  const StreetGeneratorConfig c = street_generator_config(t);
  const std::string out = test::scratch("failed_sample");
  fs::create_directories(out);
  EXPECT_THROW(generate_street_sample(c, 0, out), Error);
  EXPECT_FALSE(fs::exists(fs::path(out) / "000000"));
  EXPECT_TRUE(fs::is_empty(out)) << "a failed sample leaves no folder, final or temporary";
}

TEST(StreetGenerator, ConfigErrorsNameTheKey) {
  nlohmann::json t = test::tiny_generator_tree(1);
  t["sky"]["elevation_max_deg"] = 95.0;
  try {
    street_generator_config(t);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("sky.elevation_max_deg"), std::string::npos) << e.what();
  }
}

TEST(StreetGenerator, HdriLightingUsesTheRotatedPeak) {
  const std::string folder = test::shared_data("hdri");
  if (!fs::exists(folder)) GTEST_SKIP() << "shared data folder " << folder << " is absent";
  nlohmann::json t = test::tiny_generator_tree(1);
  t["sky"]["hdri_folder"] = folder;
  t["insertion"]["enabled"] = false;
  const StreetGeneratorConfig c = street_generator_config(t);
  const std::string out = test::scratch("hdri_sample");
  fs::create_directories(out);
  const GeneratedSample g = generate_street_sample(c, 0, out);
  std::ifstream f(fs::path(out) / g.id / "meta.json");
  const nlohmann::json meta = nlohmann::json::parse(f);
  EXPECT_EQ(meta["lighting"]["source"], "hdri");
  EXPECT_TRUE(meta["lighting"].contains("hdri_rotation_deg"));
  EXPECT_NEAR(glm::length(glm::dvec3(meta["sun_direction"][0], meta["sun_direction"][1], meta["sun_direction"][2])),
              1.0, 1e-9);
}

}  // namespace
}  // namespace sl::test
