// streetlight-bench insert: object insertion's error against run time, and its cost at the
// training and paper settings.
//
// Scene: CesiumMilkTruck (or a procedural box when the model is absent) on the ground, seen by
// a 256×144 camera, lit by a real HDRI (or a Preetham sky when absent), with the default VSG
// volume (64×64×16) of random parameters so the radiance query does real work.
// Part 1: forward time and RMSE of the composite against a high-sample reference, at
//   increasing light/shadow sample counts, with uniform (training) and importance (inference)
//   sampling -> OUT/insert_bench.csv and OUT/insert_bench.png.
// Part 2: forward and backward time and peak tensor memory of exactly what the trainer runs
//   (train/adversarial_stage.cpp with default_train_config(): a 128×64 view, aa 1, 16 light
//   samples per primary sample, an 80×45 shadow map with 128 rays, I_a 0.1, K = 64 volume
//   samples, VSG 64×64×16, cosine sampling) and the paper's (5000 foreground rays; 160×90, 450;
//   VSG 256×256×64).
// --size kitti|nuscenes: the production table (bench_insert_production.h).
#include <omp.h>
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/procedural_car.h"
#include "data/sky_model.h"
#include "data/street_generator.h"
#include "nn/checkpoint.h"
#include "render/gltf_loader.h"
#include "render/object_insertion.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "tools/bench/bench.h"
#include "tools/bench/bench_insert_production.h"
#include "tools/bench/insert_rows.h"
#include "tools/bench/kitti_frame.h"
#include "tools/bench/reference_store.h"
#include "tools/bench/timing.h"
#include "tools/common/plot.h"
#include "tools/common/cli.h"
#include "train/inference.h"
#include "train/lighting_predictor.h"
#include "train/object_labels.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"
#include "train/train_config.h"
#include "util/math.h"

using sl::data::ImageWriteOptions;
using sl::data::PreethamSky;
using sl::data::read_image;
using sl::data::SkyParams;
using sl::data::StreetGeneratorConfig;
using sl::data::write_image;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::EnvironmentMap;
using sl::render::insert_objects;
using sl::render::InsertionOptions;
using sl::render::InsertionResult;
using sl::render::Intrinsics;
using sl::render::intrinsics_from_fov;
using sl::render::load_gltf;
using sl::render::make_box;
using sl::render::make_ground_plane;
using sl::render::Material;
using sl::render::Mesh;
using sl::render::PathTracer;
using sl::render::PathTracerOptions;
using sl::render::place_object;
using sl::render::PlacedObject;
using sl::render::resize_panorama;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::vsg_activate;
using sl::render::VsgGrid;

namespace sl::bench {
namespace {

struct Scene {
  Camera camera;
  Tensor background, depth, env;
  Mesh object;
  std::string object_name, sky_name;
};

Scene make_scene(const std::string& data) {
  Scene s;
  const int W = 256, H = 144;
  s.camera = Camera(intrinsics_from_fov(60 * kDegToRad, W, H), rotation_from_yaw_pitch_roll(0, -10 * kDegToRad, 0), {0, 1.6, 0});
  std::vector<double> d(size_t(W) * H);
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const CameraRay r = s.camera.pixel_ray(j, i);
      d[size_t(i) * W + j] =
          r.direction.y < -1e-6 ? s.camera.world_to_camera(r.origin + (-1.6 / r.direction.y) * r.direction).z : INFINITY;
    }
  s.depth = Tensor::from_vector(d, {H, W});
  const std::string hdri = data + "/hdri/chinese_garden_1k.hdr", truck = data + "/models/CesiumMilkTruck.glb";
  if (std::filesystem::exists(hdri)) {
    s.env = resize_panorama(read_image(hdri), 128, 64);
    s.sky_name = "chinese_garden_1k.hdr";
  } else {
    s.env = resize_panorama(PreethamSky(SkyParams{}).render(128, 256), 128, 64);
    s.sky_name = "preetham (default parameters)";
  }
  if (std::filesystem::exists(truck)) {
    s.object = load_gltf(truck);
    s.object_name = "CesiumMilkTruck.glb";
  } else {
    s.object = make_box({-1.0f, 0.0f, -2.0f}, {1.0f, 1.8f, 2.0f});
    s.object_name = "procedural box";
  }
  Material ground;
  ground.base_color_factor = glm::vec4(0.35f, 0.35f, 0.35f, 1);
  ground.metallic = 0;
  ground.roughness = 1;
  const EnvironmentMap env_map(s.env);
  PathTracerOptions pt;
  pt.spp = 16;
  pt.max_depth = 2;
  s.background = PathTracer(make_ground_plane(400.0f, 0.0f, ground), env_map).render(s.camera, pt).radiance;
  return s;
}

// RMSE over pixels whose object coverage equals the reference's: anti-aliasing jitter differs
// between seeds and would otherwise set an error floor that no lighting sample count moves.
double rmse(const InsertionResult& a, const InsertionResult& ref) {
  const auto va = a.composite.to_vector(), vb = ref.composite.to_vector();
  const auto ma = a.object_mask.to_vector(), mb = ref.object_mask.to_vector();
  const size_t hw = ma.size();
  double e = 0;
  size_t n = 0;
  for (size_t p = 0; p < hw; ++p) {
    if (ma[p] != mb[p]) continue;
    for (size_t c = 0; c < 3; ++c) e += (va[c * hw + p] - vb[c * hw + p]) * (va[c * hw + p] - vb[c * hw + p]);
    n += 3;
  }
  return std::sqrt(e / double(std::max<size_t>(n, 1)));
}

long max_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024;
}

int run_insert(const std::vector<std::string>& args) {
  bool json = false, quick = false;
  std::string out = "insert-bench", data = "../shared/data", size, reference_dir, only, lighting = "random";
  int reference_spp = 4096, bias_runs = 0;
  bool reference_cache = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench insert [--size kitti|nuscenes] [--data DIR] [--out DIR] [--quick] [--json]\n"
          "  Object insertion error against time (uniform vs importance sampling) and the forward/backward\n"
          "  time and peak memory at the training defaults and the paper's settings.\n"
          "  --data DIR  shared data folder (default ../shared/data; falls back to a box and a Preetham sky)\n"
          "  --out DIR   where to write insert_bench.csv and insert_bench.png (default insert-bench)\n"
          "  --quick     skip the paper-scale run (with --size: only the production row)\n"
          "  --size S    production table: lighting + insertion at KITTI (1242x375) or nuScenes (1600x900)\n"
          "              size, error against a 4096-samples-per-pixel reference; --json gives ms and rel_rmse\n"
          "  --reference-spp N  light samples per pixel and shadow rays of that reference (default 4096)\n"
          "  --reference-cache  the reference reads the volume through the radiance cache too (measures sampling\n"
          "                     error alone; the default marches the volume for every ray)\n"
          "  --reference-dir DIR  keep the reference in DIR keyed by everything that determines it and reuse it\n"
          "                     (development only: the renderer's code is named by a version string, not hashed)\n"
          "  --rows A,B         with --size: only these rows (names as printed)\n"
          "  --bias-runs K      with --size: each row's bias as the mean of K more renders against the reference,\n"
          "                     less that mean's noise; its error image goes to OUT/bias_ROW.exr\n"
          "  --lighting L       with --size: the insertion's lighting. random (default): the chinese_garden sky and\n"
          "                     a VSG volume of uniform random parameters, a stress case whose volume is noise;\n"
          "                     released, or a checkpoint path: that model's estimate for the photo, as\n"
          "                     streetlight-insert renders it. The lighting time of every row is that model's\n"
          "                     inference for the photo (the released model with random), wall and CPU time\n");
      return 0;
    } else if (a == "--json") {
      json = true;
    } else if (a == "--quick") {
      quick = true;
    } else if (a == "--reference-cache") {
      reference_cache = true;
    } else if (a == "--reference-spp" && i + 1 < args.size()) {
      reference_spp = std::stoi(args[++i]);
      SL_CHECK(reference_spp >= 1, "insert: --reference-spp must be >= 1");
    } else if (a == "--bias-runs" && i + 1 < args.size()) {
      bias_runs = std::stoi(args[++i]);
      SL_CHECK(bias_runs >= 0, "insert: --bias-runs must be >= 0");
    } else if (a == "--rows" && i + 1 < args.size()) {
      only = args[++i];
    } else if (a == "--lighting" && i + 1 < args.size()) {
      lighting = args[++i];
      if (lighting == "released") lighting = cli::released_model_path();
    } else if ((a == "--out" || a == "--data" || a == "--size" || a == "--reference-dir") && i + 1 < args.size()) {
      (a == "--out" ? out : a == "--data" ? data : a == "--size" ? size : reference_dir) = args[++i];
    } else {
      fail("insert: unknown option '", a, "' (try --help)");
    }
  }
  if (!size.empty())
    return run_production(size, json, data, out, quick, reference_spp, reference_cache, reference_dir, only, lighting, bias_runs);
  std::filesystem::create_directories(out);
  const Scene s = make_scene(data);
  const PlacedObject obj = place_object(s.object, {0.8, -10.0, 30.0, 1.0}, s.camera, s.depth);
  VsgGrid grid;
  grid.center = s.camera.position();
  Tensor raw = Tensor::uniform({8, grid.dims[0], grid.dims[1], grid.dims[2]}, -4, 0, 11);
  const Tensor vsg = vsg_activate(raw, 0).detach().contiguous();  // mostly transparent, some opacity
  std::fprintf(stderr, "insert bench: %s under %s, image 256x144, VSG %lldx%lldx%lld\n", s.object_name.c_str(),
               s.sky_name.c_str(), (long long)grid.dims[0], (long long)grid.dims[1], (long long)grid.dims[2]);

  // ---- part 1: error against time
  InsertionOptions ref_opt;
  ref_opt.aa_samples = 2;
  ref_opt.light_samples = 512;
  ref_opt.shadow_rays = 1024;
  ref_opt.importance_sampling = true;
  const InsertionResult reference = insert_objects({s.background, s.depth, s.camera, s.env, vsg, grid, {obj}}, ref_opt);
  std::vector<cli::PlotPoint> points;
  std::ofstream csv(out + "/insert_bench.csv");
  csv << "mode,light_samples,shadow_rays,time_ms,rmse\n";
  for (bool importance : {false, true})
    for (int n : {4, 16, 64, 256}) {
      InsertionOptions o = ref_opt;
      o.importance_sampling = importance;
      o.light_samples = n;
      o.shadow_rays = 2 * n;
      o.seed = 1;  // independent of the reference's samples
      InsertionResult res;
      const double ms = best_ms([&] { res = insert_objects({s.background, s.depth, s.camera, s.env, vsg, grid, {obj}}, o); }, 3, 0);
      const double err = rmse(res, reference);
      const char* mode = importance ? "importance" : "uniform";
      points.push_back({mode, ms, err});
      csv << mode << ',' << n << ',' << 2 * n << ',' << ms << ',' << err << '\n';
      if (json)
        std::printf("{\"bench\": \"insert\", \"mode\": \"%s\", \"light_samples\": %d, \"shadow_rays\": %d, \"ms\": %.1f, \"rmse\": %.5g}\n",
                    mode, n, 2 * n, ms, err);
      else
        std::printf("%-10s light %4d shadow %4d  %9.1f ms  rmse %.5g\n", mode, n, 2 * n, ms, err);
      std::fflush(stdout);
    }
  ImageWriteOptions wo;
  write_image(out + "/insert_bench.png", cli::error_time_plot(points), wo);

  // ---- part 2: training-scale cost, forward + backward into env and vsg
  struct Setting {
    const char* name;
    InsertionOptions opt;
    VsgGrid grid;
    Camera camera;
    Tensor depth, background;
  };
  // The training row uses the options train/adversarial_stage.cpp uses (the same function, on
  // the default config), on a view of the street dataset's size (data/street_generator.h).
  const nlohmann::json tc = train::default_train_config();
  InsertionOptions train_opt = train::training_insertion_options(tc, 0);
  VsgGrid train_grid = grid;
  const auto dims = tc.at("model").at("volume").at("dims");
  train_grid.dims = {dims[0].get<int64_t>(), dims[1].get<int64_t>(), dims[2].get<int64_t>()};
  const StreetGeneratorConfig gen;
  const Camera train_cam(intrinsics_from_fov(60 * kDegToRad, gen.view_width, gen.view_height),
                         rotation_from_yaw_pitch_roll(0, -10 * kDegToRad, 0), {0, 1.6, 0});
  const Tensor train_depth = train::ground_plane_depth(train_cam);
  const Tensor train_bg = Tensor::full({3, gen.view_height, gen.view_width}, 0.3);
  InsertionOptions paper_opt;
  paper_opt.aa_samples = 1;
  paper_opt.foreground_rays = 5000;
  paper_opt.shadow_width = 160;
  paper_opt.shadow_height = 90;
  paper_opt.shadow_rays = 450;
  VsgGrid paper_grid = grid;
  paper_grid.dims = {256, 256, 64};
  std::vector<Setting> settings = {{"training", train_opt, train_grid, train_cam, train_depth, train_bg}};
  if (!quick) settings.push_back({"paper", paper_opt, paper_grid, s.camera, s.depth, s.background});
  for (const Setting& st : settings) {
    const InsertionOptions& o = st.opt;
    const PlacedObject sobj = place_object(s.object, {0.8, -10.0, 30.0, 1.0}, st.camera, st.depth);
    Tensor v = vsg_activate(Tensor::uniform({8, st.grid.dims[0], st.grid.dims[1], st.grid.dims[2]}, -4, 0, 12), 0)
                   .detach()
                   .contiguous()
                   .set_requires_grad(true);
    Tensor e = s.env.clone().set_requires_grad(true);
    Storage::reset_peak_bytes();
    const int64_t base = Storage::live_bytes();
    double t0 = now_ms();
    const InsertionResult r = insert_objects({st.background, st.depth, st.camera, e, v, st.grid, {sobj}}, o);
    const double fwd = now_ms() - t0;
    t0 = now_ms();
    backward(sum(r.composite));
    const double bwd = now_ms() - t0;
    const double peak_mb = double(Storage::peak_bytes() - base) / (1 << 20);
    const long long fg_light_rays = (long long)(r.stats.query_rays - r.stats.shadow_pixels_computed * o.shadow_rays);
    const Intrinsics& k = st.camera.intrinsics();
    if (json)
      std::printf("{\"bench\": \"insert_cost\", \"setting\": \"%s\", \"width\": %d, \"height\": %d, \"aa\": %d, "
                  "\"light_samples\": %d, \"foreground_budget\": %lld, \"shadow_map\": \"%dx%d\", \"shadow_rays\": %d, "
                  "\"volume_samples\": %d, \"foreground_rays\": %lld, \"query_rays\": %lld, "
                  "\"shadow_texels_computed\": %lld, \"shadow_texels\": %lld, \"forward_ms\": %.1f, \"backward_ms\": %.1f, "
                  "\"ms\": %.1f, \"peak_tensor_mb\": %.1f, \"max_rss_mb\": %ld}\n",
                  st.name, k.width, k.height, o.aa_samples, o.light_samples, (long long)o.foreground_rays, o.shadow_width,
                  o.shadow_height, o.shadow_rays, o.query.samples, fg_light_rays, (long long)r.stats.query_rays,
                  (long long)r.stats.shadow_pixels_computed, (long long)r.stats.shadow_pixels_total, fwd, bwd, fwd + bwd,
                  peak_mb, max_rss_mb());
    else
      std::printf("%-9s %dx%d aa %d light %d budget %lld shadow %dx%dx%d K %d: fg light rays %6lld  query rays %8lld  "
                  "shadow texels %lld/%lld  forward %8.1f ms  backward %8.1f ms  peak tensors %7.1f MB  max RSS %ld MB\n",
                  st.name, k.width, k.height, o.aa_samples, o.light_samples, (long long)o.foreground_rays, o.shadow_width,
                  o.shadow_height, o.shadow_rays, o.query.samples, fg_light_rays, (long long)r.stats.query_rays,
                  (long long)r.stats.shadow_pixels_computed, (long long)r.stats.shadow_pixels_total, fwd, bwd, peak_mb,
                  max_rss_mb());
    std::fflush(stdout);
  }
  return 0;
}

const Registrar reg("insert", "object insertion: error against time, and cost at training/paper settings", &run_insert);

}  // namespace
}  // namespace sl::bench
