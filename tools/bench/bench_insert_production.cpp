// streetlight-bench insert --size kitti|nuscenes: the production table. Lighting (the released
// model's inference for the photo, as streetlight-insert runs it; wall and CPU time) plus
// insertion at 1242×375 (KITTI 000008 with lidar depth) or 1600×900 (nuScenes CAM_FRONT
// intrinsics, ground plane), one row per approximation knob (insert_rows.h), each with its error
// against a 4096-samples-per-pixel reference of the same renderer over the object and its shadow
// region, and its noise (a second run with independent light and shadow samples: RMSE between the
// two / √2), so the error splits into noise and bias (rel_rmse² ≈ noise² + bias²).
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
#include "nn/checkpoint.h"
#include "render/environment_map.h"
#include "render/gltf_loader.h"
#include "render/object_insertion.h"
#include "tools/bench/bench.h"
#include "tools/bench/bench_insert_production.h"
#include "tools/bench/insert_rows.h"
#include "tools/bench/kitti_frame.h"
#include "tools/bench/reference_store.h"
#include "tools/bench/timing.h"
#include "tools/common/cli.h"
#include "train/inference.h"
#include "train/lighting_predictor.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"
#include "train/train_config.h"
#include "util/math.h"

using sl::data::make_procedural_car;
using sl::data::PreethamSky;
using sl::data::read_image;
using sl::data::SkyParams;
using sl::data::to_object_frame;
using sl::data::write_image;
using sl::render::Camera;
using sl::render::insert_objects;
using sl::render::InsertionInputs;
using sl::render::InsertionOptions;
using sl::render::InsertionResult;
using sl::render::Intrinsics;
using sl::render::load_gltf;
using sl::render::Mesh;
using sl::render::place_object;
using sl::render::Placement;
using sl::render::resize_panorama;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::vsg_activate;

namespace sl::bench {
namespace {

// ---- production sizes : lighting + insertion at KITTI 1242×375 and nuScenes 1600×900

// Relative RMSE of the composite over the object and its shadow region: pixels the reference's
// object covers, or whose reference shadow ratio differs from 1 by more than 1e-3. Both
// renders use the same anti-aliasing samples (same seed), so coverage is identical and the
// error is the lighting estimate's alone. (The rows also report process CPU time, cpu_now_ms of
// timing.h: on a loaded machine, wall time ≈ that / threads is what an idle machine would show.)

struct RegionError {
  double rel_rmse = 0;
  int64_t pixels = 0;
  // The same error split by where it lands, as sqrt(Σ e² over the part / Σ ref² over the whole
  // region), so the three add in quadrature to rel_rmse: pixels fully covered by the object
  // (foreground sampling, Eq. 2), partly covered (edges: both terms), and not covered (the
  // ratio shadow map alone, Eq. 3-4).
  double object = 0, edge = 0, shadow = 0;
  int64_t object_pixels = 0, edge_pixels = 0, shadow_pixels = 0;
};

RegionError region_error(const InsertionResult& a, const InsertionResult& ref) {
  const auto va = a.composite.to_vector(), vr = ref.composite.to_vector();
  const auto mr = ref.object_mask.to_vector(), sr = ref.shadow_map.to_vector();
  const size_t hw = mr.size();
  double e = 0, r2 = 0, e_part[3] = {0, 0, 0};
  RegionError out;
  int64_t* counts[3] = {&out.object_pixels, &out.edge_pixels, &out.shadow_pixels};
  for (size_t p = 0; p < hw; ++p) {
    const double s = (sr[p] + sr[hw + p] + sr[2 * hw + p]) / 3.0;
    if (mr[p] <= 0 && std::abs(s - 1.0) <= 1e-3) continue;
    ++out.pixels;
    const int part = mr[p] >= 1 ? 0 : mr[p] > 0 ? 1 : 2;
    ++*counts[part];
    for (size_t c = 0; c < 3; ++c) {
      const double d = va[c * hw + p] - vr[c * hw + p];
      e += d * d;
      e_part[part] += d * d;
      r2 += vr[c * hw + p] * vr[c * hw + p];
    }
  }
  out.rel_rmse = r2 > 0 ? std::sqrt(e / r2) : 0.0;
  out.object = r2 > 0 ? std::sqrt(e_part[0] / r2) : 0.0;
  out.edge = r2 > 0 ? std::sqrt(e_part[1] / r2) : 0.0;
  out.shadow = r2 > 0 ? std::sqrt(e_part[2] / r2) : 0.0;
  return out;
}

struct ProductionScene {
  std::string name, depth_source;
  train::Photo photo;
  Mesh object;  // object frame (data/object_placement.h)
  Placement pose;
};

ProductionScene production_scene(const std::string& size, const std::string& data) {
  ProductionScene s;
  const std::string kitti = data + "/street/kitti_000008", truck = data + "/models/CesiumMilkTruck.glb";
  s.object = to_object_frame(std::filesystem::exists(truck) ? load_gltf(truck) : make_procedural_car());
  s.pose.yaw_deg = 60.0;
  if (size == "kitti" && std::filesystem::exists(kitti + "/000008.png")) {
    s.photo = train::load_photo(kitti_000008(kitti));
    s.name = "KITTI 000008 (lidar depth)";
    s.pose.x_m = 1.5;
    s.pose.z_m = -11.0;
  } else {
    const bool nus = size == "nuscenes";
    const int W = nus ? 1600 : 1242, H = nus ? 900 : 375;
    Intrinsics k;
    k.width = W;
    k.height = H;
    k.fx = k.fy = nus ? 1266.4 : 721.5;
    k.cx = nus ? 816.3 : 609.6;
    k.cy = nus ? 491.5 : 172.9;
    s.photo.camera = Camera(k, rotation_from_yaw_pitch_roll(0, 0, 0), {0.0, nus ? 1.5 : 1.65, 0.0});
    s.photo.depth = train::ground_plane_depth(s.photo.camera);
    s.photo.depth_source = "ground-plane";
    Tensor img = Tensor::zeros({3, H, W});
    float* p = img.data<float>();
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < H; ++r)
        for (int x = 0; x < W; ++x) p[(int64_t(c) * H + r) * W + x] = r < int(k.cy) ? 0.55f + 0.1f * c : 0.38f;
    s.photo.ldr = img;
    s.name = nus ? "nuScenes-size CAM_FRONT intrinsics (ground plane)" : "KITTI-size (ground plane; data absent)";
    s.pose.x_m = 1.5;
    s.pose.z_m = -11.0;
  }
  return s;
}

// Lighting inference time, wall and process CPU (best of 5 after a warm-up), of what
// streetlight-insert runs for the photo: LightingEstimator::estimate() with its defaults (flip
// averaging, the visible-sun cue with the released sun-glare detector) on `model`, a lighting checkpoint: the released model unless
// --lighting names another. Without one (a checkout without models/), the default-size model
// with random initial weights (timing does not depend on the weights, but the released model's
// backbone is narrower than the default), left in OUT/random_default_lighting.safetensors.
struct LightingTime {
  double wall_ms = 0, cpu_ms = 0;
  std::string model;
};
LightingTime lighting_ms(const train::Photo& photo, std::string model, const std::string& dir) {
  if (model.empty()) {
    nlohmann::json c = train::default_train_config();
    c["stage"] = "lighting";
    nn::Module holder("LightingModel");
    holder.register_module("predictor", std::make_shared<train::LightingPredictor>(train::predictor_options(c)));
    model = dir + "/random_default_lighting.safetensors";
    nn::save_checkpoint(model, holder, nullptr, nn::CheckpointInfo{.stage = "lighting", .step = 0, .config_json = c.dump()});
  }
  train::LightingEstimator est(model);
  // As streetlight-insert: the released sun-glare detector behind the disk test, when present.
  if (const std::string glare = cli::released_sun_glare_path(); !glare.empty()) est.set_sun_glare(train::load_sun_glare(glare));
  LightingTime t{1e300, 1e300, model};
  const train::InferenceView view{photo.ldr, photo.depth, photo.camera};
  est.estimate({view});  // warm-up
  for (int i = 0; i < 5; ++i) {
    const double w0 = now_ms(), c0 = cpu_now_ms();
    est.estimate({view});
    t.cpu_ms = std::min(t.cpu_ms, cpu_now_ms() - c0);
    t.wall_ms = std::min(t.wall_ms, now_ms() - w0);
  }
  return t;
}

}  // namespace

int run_production(const std::string& size, bool json, const std::string& data, const std::string& out, bool quick,
                   int reference_spp, bool reference_cache, const std::string& reference_dir, const std::string& only,
                   const std::string& lighting, int bias_runs) {
  SL_CHECK(size == "kitti" || size == "nuscenes", "insert: --size must be kitti or nuscenes, got '", size, "'");
  std::filesystem::create_directories(out);
  const ProductionScene s = production_scene(size, data);
  const Intrinsics& k = s.photo.camera.intrinsics();
  std::fprintf(stderr, "insert bench (%s): %s, %dx%d, %d threads\n", size.c_str(), s.name.c_str(), k.width, k.height,
               omp_get_max_threads());
  std::string timed_model = lighting != "random" ? lighting : "";
  if (timed_model.empty()) try {
      timed_model = cli::released_model_path();
    } catch (const Error&) {
      std::fprintf(stderr, "lighting: the released model is missing; timing the default-size model with random weights\n");
    }
  const LightingTime light = lighting_ms(s.photo, timed_model, out);
  const double light_ms = light.wall_ms;
  std::fprintf(stderr, "lighting inference (%s, LightingEstimator::estimate with its defaults): %.0f ms (CPU %.0f ms)\n",
               light.model.c_str(), light.wall_ms, light.cpu_ms);

  // Insertion lighting: a real sky with a sun at the model's dome size, and a default-size VSG
  // volume of random parameters, so the radiance query does the work a trained model gives it.
  const std::string hdri = data + "/hdri/chinese_garden_1k.hdr";
  InsertionInputs in;
  in.background = pow_scalar(s.photo.ldr.to(DType::F32).contiguous(), kLdrGamma);
  in.depth = s.photo.depth.to(DType::F32).contiguous();
  in.camera = s.photo.camera;
  in.env = std::filesystem::exists(hdri) ? resize_panorama(read_image(hdri), 128, 32)
                                         : resize_panorama(PreethamSky(SkyParams{}).render(128, 256), 128, 32);
  in.grid.center = s.photo.camera.position();
  in.vsg = vsg_activate(Tensor::uniform({8, in.grid.dims[0], in.grid.dims[1], in.grid.dims[2]}, -4, 0, 11), 0).detach().contiguous();
  Placement pl;
  pl.x_m = s.pose.x_m;
  pl.z_m = s.pose.z_m;
  pl.yaw_deg = s.pose.yaw_deg;
  if (lighting != "random") {
    // The lighting a trained model estimates for this photo (what streetlight-insert renders
    // with), in the model's canonical frame; the object's pose follows into that frame.
    train::LightingEstimator est(lighting);
    const train::EstimatedLighting l = est.estimate({{s.photo.ldr, s.photo.depth, s.photo.camera}});
    SL_CHECK(l.vsg.defined(), "insert: --lighting '", lighting, "' has no volume branch");
    in.env = l.env;
    in.vsg = l.vsg;
    in.grid = l.grid;
    in.camera = l.camera;
    const glm::dvec3 c = l.frame.point({pl.x_m, 0.0, pl.z_m});
    pl.x_m = c.x;
    pl.z_m = c.z;
    pl.yaw_deg = l.frame.object_yaw_deg(pl.yaw_deg);
    std::fprintf(stderr, "insertion lighting: %s's estimate for the photo\n", lighting.c_str());
  } else {
    std::fprintf(stderr, "insertion lighting: chinese_garden sky + a VSG volume of uniform random parameters (stress)\n");
  }
  in.objects.push_back(place_object(s.object, pl, in.camera, in.depth));

  const train::PhotoInsertionOptions production;  // what streetlight-insert runs by default
  // The reference: `reference_spp` light samples per pixel and shadow rays, as the mean of
  // passes of 64 light samples per primary ray and 256 shadow rays with independent lighting
  // seeds (same anti-aliasing samples), so memory stays that of one pass.
  InsertionOptions ref = train::insertion_options(production);
  ref.light_samples = 64;
  ref.shadow_rays = 256;
  ref.radiance_cache = reference_cache;
  ref.diffuse_control_variate = false;  // plain Eq. 2: the control variate's bias stays visible
  ref.adaptive_light_samples = 0;        // and so do adaptive sampling's
  ref.denoise_radius = 0;                // and the residual filter's
  const int passes = std::max({1, reference_spp / (ref.aa_samples * ref.light_samples), reference_spp / ref.shadow_rays});
  double ref_ms = 0;
  InsertionResult reference;
  // A stored reference (--reference-dir) is keyed by everything that determines it; the
  // renderer's code is named by kReferenceRenderer, bumped whenever an expectation changes.
  Fingerprint key;
  key.text("insertion reference; renderer v4");  // v2: Owen-scrambled primary samples; v3: the key names every probe knob of a cache reference; v4: single-precision panorama coordinates of BRDF samples
  for (const Tensor& t : {in.background, in.depth, in.env, in.vsg}) key.tensor(t);
  key.bytes(in.objects[0].mesh.positions.data(), in.objects[0].mesh.positions.size() * sizeof(glm::vec3));
  key.value(k);
  key.value(in.camera.rotation());
  key.value(in.camera.position());
  key.value(in.grid);
  for (int v : {passes, ref.aa_samples, ref.light_samples, ref.shadow_rays, ref.shadow_width, ref.shadow_height,
                int(ref.radiance_cache), int(ref.importance_sampling), int(ref.prune)})
    key.value(v);
  if (ref.radiance_cache) {  // the probes shape a cache reference only
    for (int v : {ref.cache_height, ref.cache_width, ref.cache_max_xz, ref.cache_max_y, ref.cache_shadow_max_xz,
                  ref.cache_shadow_max_y, ref.cache_shadow_height})
      key.value(v);
    key.value(ref.cache_spacing_m);
    key.value(ref.cache_shadow_exact_sky);
  }
  key.value(ref.ambient);
  key.value(ref.seed);
  for (double v : {double(ref.query.samples), double(ref.query.spacing), double(ref.query.trilinear),
                   double(ref.query.prune), ref.query.empty_alpha, ref.query.min_transmittance})
    key.value(v);
  const std::string stored = reference_dir.empty() ? "" : reference_dir + "/insert_reference_" + key.hex() + ".bin";
  std::vector<Tensor> kept;
  if (!stored.empty() && load_tensors(stored, kept, 4)) {
    reference.composite = kept[0];
    reference.shadow_map = kept[1];
    reference.object_mask = kept[2];
    reference.object_silhouette = kept[3];
    std::fprintf(stderr, "reference: loaded %s (a stored reference; the final figures need a fresh one)\n", stored.c_str());
  } else {
    const double t0 = now_ms();
    Tensor comp, shadow;
    for (int p = 0; p < passes; ++p) {
      ref.lighting_seed = uint64_t(1000 + p);  // independent of the rows' light and shadow samples
      InsertionResult r = insert_objects(in, ref);
      comp = p == 0 ? r.composite : add(comp, r.composite);
      shadow = p == 0 ? r.shadow_map : add(shadow, r.shadow_map);
      if (p == 0) reference = r;
    }
    reference.composite = mul_scalar(comp, 1.0 / passes).contiguous();
    reference.shadow_map = mul_scalar(shadow, 1.0 / passes).contiguous();
    ref_ms = now_ms() - t0;
    std::fprintf(stderr, "reference (%d passes: %d light samples per pixel, %d shadow rays, %s): %.1f s\n", passes,
                 passes * ref.aa_samples * ref.light_samples, passes * ref.shadow_rays,
                 reference_cache ? "radiance cache" : "exact queries", ref_ms / 1000);
    if (!stored.empty()) {
      std::filesystem::create_directories(reference_dir);
      store_tensors(stored, {reference.composite, reference.shadow_map, reference.object_mask, reference.object_silhouette});
      std::fprintf(stderr, "reference: stored %s\n", stored.c_str());
    }
  }
  const std::vector<InsertRow> rows = insert_rows(production, quick);
  for (const InsertRow& row : rows) {
    if (!only.empty() && ("," + only + ",").find("," + row.name + ",") == std::string::npos) continue;
    InsertionResult r;
    double cpu_ms = 1e300;
    const double ms = best_ms([&] {
      const double c0 = cpu_now_ms();
      r = insert_objects(in, row.opt);
      cpu_ms = std::min(cpu_ms, cpu_now_ms() - c0);
    }, 2, 0);
    const RegionError err = region_error(r, reference);
    // The row's bits (composite and shadow map): a change meant to be exact keeps this line.
    Fingerprint bits;
    bits.tensor(r.composite);
    bits.tensor(r.shadow_map);
    std::fprintf(stderr, "%s: output fingerprint %s\n", row.name.c_str(), bits.hex().c_str());
    // Noise alone: the same row with independent light and shadow samples; the RMSE between
    // the two, / √2, is one run's standard deviation (the rest of rel_rmse is bias).
    InsertionOptions other = row.opt;
    other.lighting_seed = 77;
    const RegionError noise = region_error(insert_objects(in, other), r);
    // Bias alone (--bias-runs K): the mean of K more renders with independent light and shadow
    // samples against the reference. Its noise is one run's / √K, subtracted in quadrature; the
    // mean's error image (|mean − reference| summed over channels, in radiance: red where the mean
    // is brighter, blue where darker) is written to OUT/bias_<row>.exr so the bias can be looked
    // at, not only counted.
    RegionError bias;
    if (bias_runs > 0) {
      InsertionResult mean = r;
      Tensor sum;
      for (int i = 0; i < bias_runs; ++i) {
        InsertionOptions o = row.opt;
        o.lighting_seed = 1000 + uint64_t(i);
        const Tensor c = insert_objects(in, o).composite;
        sum = i == 0 ? c : add(sum, c);
      }
      mean.composite = mul_scalar(sum, 1.0 / bias_runs).contiguous();
      bias = region_error(mean, reference);
      const double floor2 = noise.rel_rmse * noise.rel_rmse / 2.0 / bias_runs;
      const double floor2_object = noise.object * noise.object / 2.0 / bias_runs;
      bias.rel_rmse = std::sqrt(std::max(0.0, bias.rel_rmse * bias.rel_rmse - floor2));
      bias.object = std::sqrt(std::max(0.0, bias.object * bias.object - floor2_object));
      const auto d = sub(mean.composite, reference.composite).to_vector();
      const int64_t hw = r.object_mask.numel();
      std::vector<double> v(size_t(3 * hw), 0.0);
      for (int64_t p = 0; p < hw; ++p) {
        const double e = std::abs(d[p]) + std::abs(d[hw + p]) + std::abs(d[2 * hw + p]);
        v[size_t((d[p] + d[hw + p] + d[2 * hw + p] > 0 ? 0 : 2) * hw + p)] = e;
      }
      write_image(out + "/bias_" + row.name + ".exr", Tensor::from_vector(v, r.composite.shape()));
    }
    const double total = light_ms + ms;
    if (json)
      std::printf("{\"bench\": \"insert_production\", \"size\": \"%s\", \"row\": \"%s\", \"width\": %d, \"height\": %d, "
                  "\"aa\": %d, \"light_samples\": %d, \"shadow_rays\": %d, \"shadow_map\": \"%dx%d\", \"radiance_cache\": %s, "
                  "\"lighting_ms\": %.1f, \"lighting_cpu_ms\": %.1f, \"insertion_ms\": %.1f, \"ms\": %.1f, \"rel_rmse\": %.5f, \"region_pixels\": %lld, "
                  "\"insertion_cpu_ms\": %.1f, \"object_samples\": %lld, \"query_rays\": %lld, \"exact_query_rays\": %lld, "
                  "\"exact_correction_rays\": %lld, \"shadow_texels_computed\": %lld, "
                  "\"rel_rmse_object\": %.5f, \"rel_rmse_edge\": %.5f, \"rel_rmse_shadow\": %.5f, \"object_pixels\": %lld, "
                  "\"edge_pixels\": %lld, \"shadow_pixels\": %lld, \"rel_noise\": %.5f, \"rel_noise_object\": %.5f, "
                  "\"rel_noise_shadow\": %.5f, \"bias_runs\": %d, \"rel_bias\": %.5f, \"rel_bias_object\": %.5f, \"reference_ms\": %.0f}\n",
                  size.c_str(), row.name.c_str(), k.width, k.height, row.opt.aa_samples, row.opt.light_samples,
                  row.opt.shadow_rays, row.opt.shadow_width, row.opt.shadow_height, row.opt.radiance_cache ? "true" : "false",
                  light_ms, light.cpu_ms, ms, total, err.rel_rmse, (long long)err.pixels, cpu_ms, (long long)r.stats.foreground_samples,
                  (long long)r.stats.query_rays, (long long)r.stats.exact_query_rays,
                  (long long)r.stats.exact_correction_rays, (long long)r.stats.shadow_pixels_computed, err.object, err.edge, err.shadow,
                  (long long)err.object_pixels, (long long)err.edge_pixels, (long long)err.shadow_pixels,
                  noise.rel_rmse / std::sqrt(2.0), noise.object / std::sqrt(2.0), noise.shadow / std::sqrt(2.0), bias_runs,
                  bias.rel_rmse, bias.object, ref_ms);
    else
      std::printf("%-26s aa %d light %4d shadow %4d (%dx%d)  lighting %6.0f ms + insertion %7.0f ms = %7.0f ms  "
                  "rel RMSE %.4f over %lld px [object %.4f, edges %.4f, shadow %.4f]  noise %.4f [object %.4f, shadow "
                  "%.4f]  (CPU: lighting %.0f ms, insertion %.0f ms; object samples %lld, query rays %lld (%lld marched exactly, %lld "
                  "for corrections), shadow texels %lld)\n",
                  row.name.c_str(), row.opt.aa_samples, row.opt.light_samples, row.opt.shadow_rays, row.opt.shadow_width,
                  row.opt.shadow_height, light_ms, ms, total, err.rel_rmse, (long long)err.pixels, err.object, err.edge,
                  err.shadow, noise.rel_rmse / std::sqrt(2.0), noise.object / std::sqrt(2.0),
                  noise.shadow / std::sqrt(2.0), light.cpu_ms, cpu_ms, (long long)r.stats.foreground_samples, (long long)r.stats.query_rays,
                  (long long)r.stats.exact_query_rays, (long long)r.stats.exact_correction_rays,
                  (long long)r.stats.shadow_pixels_computed);
    if (!json && bias_runs > 0)
      std::printf("%-26s bias %.4f [object %.4f] (the mean of %d more runs, less its noise)\n", row.name.c_str(), bias.rel_rmse,
                  bias.object, bias_runs);
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace sl::bench
