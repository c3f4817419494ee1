// streetlight-insert: inserts a glTF object into a street photo with the lighting a trained
// checkpoint estimates from the photo (Sec 3.2-3.3), or, in batch mode, random objects into
// many photos, writing an augmented dataset in KITTI layout (Sec 4.4).
//
// Outputs (single image) in --out DIR, written to a temporary sibling folder first and renamed
// only when everything succeeded, so bad input leaves nothing behind:
//   composite.png (+ composite.exr with --exr), object_mask.png, shadow_map.png, sky.exr,
//   sky.png (tone-mapped, world azimuths), depth.exr (the depth used), result.json (sun, with
//   flip_spread_deg, hedge and crop_spread_deg: the network's confidences, train/inference.h
//   sun_flip_spread_deg, sun_hedge and sun_crop_spread_deg (smaller is more confident for all), and
//   visible_sun: whether a sun disk in the photo set the direction, and its pixel; placement,
//   boxes, KITTI label line, timings; with --refine N > 0 the discriminator loss and the sun
//   before and after refinement), label.txt (the KITTI line).
// --refine N (paper Fig. 7): N Adam steps on the sky vector (and with --refine-volume the volume)
// against the stage-3 discriminator, train/lighting_refinement.h; the composite then uses the
// refined lighting. N = 0 (the default) changes nothing.
// Batch mode writes a KITTI folder in place, frame by frame (see batch() below), and resumes.
#include <algorithm>
#include <csignal>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/sun_from_shadows.h"
#include "data/kitti_labels.h"
#include "data/procedural_car.h"
#include "render/gltf_loader.h"
#include "tools/common/cli.h"
#include "train/batch_list.h"
#include "train/inference.h"
#include "train/lighting_refinement.h"
#include "train/losses.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"
#include "util/file.h"
#include "util/math.h"
#include "util/random.h"

using sl::data::cover_label;
using sl::data::footprints_within;
using sl::data::format_kitti_label;
using sl::data::ImageWriteOptions;
using sl::data::kitti_box3d;
using sl::data::kitti_calibration_from_intrinsics;
using sl::data::kitti_calibration_text;
using sl::data::KittiLabel;
using sl::data::make_procedural_car;
using sl::data::occlusion_level;
using sl::data::read_kitti_labels;
using sl::data::ShadowSunFit;
using sl::train::estimate_with_shadow_sun;
using sl::train::ShadowSunLighting;
using sl::data::to_object_frame;
using sl::data::Transfer;
using sl::data::write_depth;
using sl::data::write_image;
using sl::render::Intrinsics;
using sl::render::load_gltf;
using sl::render::Mesh;
using sl::render::Placement;
using sl::render::RadianceQueryOptions;

namespace fs = std::filesystem;
using nlohmann::json;
using namespace sl;
using namespace sl::train;

namespace {

std::pair<double, double> parse_pair(const std::string& flag, const std::string& v) {
  double a = 0, b = 0;
  char comma = 0, extra = 0;
  std::istringstream is(v);
  if (!(is >> a >> comma >> b) || comma != ',' || (is >> extra) || !std::isfinite(a) || !std::isfinite(b))
    fail(flag, " expects two numbers 'X,Z', got '", v, "'");
  return {a, b};
}

std::vector<double> parse_list(const std::string& flag, const std::string& v, size_t min_n, size_t max_n) {
  std::vector<double> out;
  std::string item;
  std::istringstream is(v);
  while (std::getline(is, item, ',')) {
    try {
      size_t used = 0;
      out.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      fail(flag, ": '", item, "' is not a number (in '", v, "')");
    }
  }
  SL_CHECK(out.size() >= min_n && out.size() <= max_n, flag, " expects ", min_n, "-", max_n,
           " comma-separated numbers, got '", v, "'");
  return out;
}

Mesh load_object(const std::string& spec) {
  if (spec == "procedural:car") return to_object_frame(make_procedural_car());
  SL_CHECK(fs::exists(spec), "object file '", spec, "' does not exist");
  return to_object_frame(load_gltf(spec));
}

// Refuses to replace an --out folder that is not a previous streetlight-insert output.
void check_replaceable(const std::string& out) {
  if (!fs::exists(out)) return;
  SL_CHECK(fs::is_directory(out) && (fs::is_empty(out) || fs::exists(fs::path(out) / "result.json") ||
                                     fs::exists(fs::path(out) / "image_2")),
           "--out '", out, "' exists and is not a previous streetlight-insert output; choose another folder");
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
  SL_CHECK(f.good(), "cannot write '", path, "'");
}

PhotoInsertionOptions insertion_options(const cli::Args& a, const RadianceQueryOptions& volume_query) {
  PhotoInsertionOptions o = a.has("--fast") ? train::fast_insertion_options() : PhotoInsertionOptions{};
  o.aa_samples = static_cast<int>(a.integer("--aa", o.aa_samples));
  o.light_samples = static_cast<int>(a.integer("--light-samples", o.light_samples));
  o.shadow_rays = static_cast<int>(a.integer("--shadow-rays", o.shadow_rays));
  o.shadow_width = static_cast<int>(a.integer("--shadow-width", o.shadow_width));
  o.shadow_height = static_cast<int>(a.integer("--shadow-height", o.shadow_height));
  o.adaptive_light_samples = a.number("--adaptive-samples", o.adaptive_light_samples);
  o.denoise_radius = static_cast<int>(a.integer("--denoise-radius", o.denoise_radius));
  o.exact_light_rays = static_cast<int>(a.integer("--exact-light-rays", o.exact_light_rays));
  o.shadow_exact_rays = static_cast<int>(a.integer("--exact-shadow-rays", o.shadow_exact_rays));
  o.radiance_cache = !a.has("--exact");
  o.seed = static_cast<uint64_t>(a.integer("--seed", 0));
  o.volume_query = volume_query;
  SL_CHECK(o.aa_samples > 0 && o.light_samples > 0 && o.shadow_rays > 0 && o.shadow_width > 0 && o.shadow_height > 0,
           "--aa, --light-samples, --shadow-rays, --shadow-width and --shadow-height must be positive");
  SL_CHECK(std::isfinite(o.adaptive_light_samples) && o.adaptive_light_samples >= 0 && o.adaptive_light_samples <= 1024,
           "--adaptive-samples must be in [0, 1024], got ", o.adaptive_light_samples);
  SL_CHECK(o.denoise_radius >= 0 && o.denoise_radius <= 16, "--denoise-radius must be in [0, 16], got ", o.denoise_radius);
  SL_CHECK(o.exact_light_rays >= 0 && o.exact_light_rays <= 64, "--exact-light-rays must be in [0, 64], got ",
           o.exact_light_rays);
  SL_CHECK(o.shadow_exact_rays >= 0 && o.shadow_exact_rays <= 64, "--exact-shadow-rays must be in [0, 64], got ",
           o.shadow_exact_rays);
  return o;
}

json vec_json(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

// The network's sun confidence (train/inference.h sun_flip_spread_deg), null when not measured.
json spread_json(const EstimatedLighting& light) {
  return std::isfinite(light.sun_flip_spread_deg) ? json(light.sun_flip_spread_deg) : json();
}

// The network's sun height, its second confidence (train/inference.h sun_hedge), null without a
// sky vector.
json hedge_json(const EstimatedLighting& light) {
  return std::isfinite(light.sun_hedge) ? json(light.sun_hedge) : json();
}

// The visible-sun cue (train/inference.h): whether the photo showed the sun disk that set the
// sun's direction, and where (the view's continuous pixel coordinates).
json visible_sun_json(const EstimatedLighting& light) {
  if (!light.visible_sun_found) return {{"found", false}};
  return {{"found", true}, {"view", light.visible_sun_view},
          {"pixel", {light.visible_sun_pixel.x, light.visible_sun_pixel.y}}, {"score", light.visible_sun_score}};
}

// The third confidence, from crop averaging (train/inference.h sun_crop_spread_deg), null when off.
json crop_spread_json(const EstimatedLighting& light) {
  return std::isfinite(light.sun_crop_spread_deg) ? json(light.sun_crop_spread_deg) : json();
}

// The estimator's options shared by the single-image and the batch mode.
void configure_estimator(LightingEstimator& est, const cli::Args& a) {
  est.set_flip_average(!a.has("--no-flip-average"));
  est.set_visible_sun(!a.has("--no-visible-sun"));
  est.set_crop_scales(a.numbers("--crop-scales", {}, 0.0, 1.0));
}

json sun_json(const EstimatedLighting& light) {
  const glm::dvec3 sun = light.sun_direction_world();
  return {{"direction_world", vec_json(sun)},
          {"azimuth_deg", azimuth_deg_of(sun)},
          {"elevation_deg", elevation_deg_of(sun)},
          {"intensity_rgb", vec_json(light.sun_intensity_rgb)},
          {"flip_spread_deg", spread_json(light)},
          {"hedge", hedge_json(light)},
          {"crop_spread_deg", crop_spread_json(light)},
          {"visible_sun", visible_sun_json(light)}};
}

// --sun-from-shadows without a confident fit: say so on stderr (the network's sun stays).
void warn_if_no_shadow_sun(const ShadowSunFit& fit, const std::string& depth_source, const std::string& frame) {
  if (fit.found) return;
  std::fprintf(stderr, "warning: --sun-from-shadows found no shadow the depth explains%s%s (score %.2f, %d ground "
               "samples, depth: %s); keeping the network's sun\n", frame.empty() ? "" : " in ", frame.c_str(), fit.score,
               fit.ground_samples, depth_source.c_str());
}

// --refine N, --refine-lr, --refine-volume, --discriminator: checked before anything is estimated
// or written. The discriminator comes from --discriminator, else from the lighting checkpoint.
struct Refinement {
  RefinementOptions options;
  std::string discriminator_path;
  std::shared_ptr<nn::PatchDiscriminator> discriminator;
  // The refinement's own sample budget (--refine-samples AA,LIGHT,SHADOW): its steps march the
  // volume exactly for every ray (no radiance cache under a gradient), and D sees the composite
  // area-averaged to the predictor's input size, so fewer samples per pixel cost little noise.
  int aa = 1, light = 4, shadow = 16;
};

Refinement refinement_from_args(const cli::Args& a, const std::string& checkpoint) {
  Refinement r;
  const int64_t steps = a.integer("--refine", 0);
  SL_CHECK(steps >= 0 && steps <= 1000000, "--refine ", steps, " must be a step count >= 0");
  r.options.steps = static_cast<int>(steps);
  r.options.lr = a.number("--refine-lr", r.options.lr);
  SL_CHECK(std::isfinite(r.options.lr) && r.options.lr > 0, "--refine-lr ", a.get("--refine-lr"), " must be positive");
  r.options.volume = a.has("--refine-volume");
  if (a.has("--refine-samples")) {
    const std::vector<double> n = parse_list("--refine-samples", a.get("--refine-samples"), 3, 3);
    for (double v : n)
      SL_CHECK(v >= 1 && v <= 1e6 && v == std::floor(v), "--refine-samples expects three positive integers AA,LIGHT,SHADOW, got '",
               a.get("--refine-samples"), "'");
    r.aa = int(n[0]), r.light = int(n[1]), r.shadow = int(n[2]);
  }
  if (steps == 0) return r;
  r.discriminator_path = a.has("--discriminator") ? a.get("--discriminator") : checkpoint;
  SL_CHECK(a.has("--discriminator") || fs::exists(checkpoint), "checkpoint '", checkpoint, "' does not exist");
  SL_CHECK(!a.has("--discriminator") || fs::exists(r.discriminator_path), "--discriminator '", r.discriminator_path,
           "' does not exist");
  r.discriminator = load_discriminator(r.discriminator_path);
  SL_CHECK(r.discriminator, "--refine ", steps, " needs the stage-3 discriminator, but '", r.discriminator_path,
           "' holds no discriminator.* tensors; give --discriminator FILE (a stage-3 checkpoint, or an export made"
           " with streetlight-export --with-discriminator)");
  return r;
}

PhotoSources sources_from_args(const cli::Args& a, size_t i) {
  const auto images = a.all("--image"), intr = a.all("--intrinsics"), poses = a.all("--pose");
  PhotoSources s;
  s.image = images[i];
  if (!intr.empty()) {
    SL_CHECK(intr.size() == images.size() || intr.size() == 1, "give one --intrinsics per --image (", images.size(),
             " images, ", intr.size(), " intrinsics) or one for all");
    s.intrinsics = intr[intr.size() == 1 ? 0 : i];
  }
  s.camera_height_m = a.number("--camera-height", 1.65);
  s.pitch_deg = a.number("--pitch", 0.0);
  if (i == 0) {
    s.depth = a.get("--depth");
    s.lidar = a.get("--lidar");
    s.calib = a.get("--calib");
  }
  if (images.size() > 1) {
    SL_CHECK(poses.size() == images.size(), "multi-view needs one --pose X,Y,Z,YAW[,PITCH] per --image (",
             images.size(), " images, ", poses.size(), " poses)");
    const std::vector<double> p = parse_list("--pose", poses[i], 4, 5);
    s.position = glm::dvec3(p[0], p[1], p[2]);
    s.yaw_deg = p[3];
    if (p.size() == 5) s.pitch_deg = p[4];
  }
  return s;
}

int single(const cli::Args& a) {
  SL_CHECK(a.has("--image") || a.has("--sample"), "--image PHOTO is required (or --sample, or --batch)");
  SL_CHECK(a.has("--object"), "--object MODEL.glb is required (or procedural:car)");
  SL_CHECK(a.has("--out"), "--out DIR is required");
  std::vector<Photo> photos;
  Placement sample_place;
  bool has_sample_place = false;
  if (a.has("--sample")) {
    photos.push_back(load_street_view(a.get("--sample"), 0, &sample_place, &has_sample_place));
  } else {
    for (size_t i = 0; i < a.all("--image").size(); ++i) photos.push_back(load_photo(sources_from_args(a, i)));
  }
  const Photo& photo = photos[0];
  const Mesh object = load_object(a.get("--object"));
  SL_CHECK(a.has("--at") || has_sample_place, "--at X,Z is required (metres right of and ahead of the first camera)");
  Placement pose;
  pose.yaw_deg = 90.0;
  double ax = 0, az = 0;
  if (a.has("--at")) {
    std::tie(ax, az) = parse_pair("--at", a.get("--at"));
    // --at is in the first camera's ground frame: X right, Z forward.
    const glm::dvec3 right = photo.camera.rotation()[0], fwd = photo.camera.rotation()[2];
    const glm::dvec3 r_h = glm::normalize(glm::dvec3(right.x, 0, right.z)), f_h = glm::normalize(glm::dvec3(fwd.x, 0, fwd.z));
    const glm::dvec3 ground = photo.camera.position() + ax * r_h + az * f_h;
    pose.x_m = ground.x;
    pose.z_m = ground.z;
    pose.yaw_deg = a.number("--yaw", 90.0);
  } else {
    pose.x_m = sample_place.x_m;
    pose.z_m = sample_place.z_m;
    pose.yaw_deg = a.number("--yaw", sample_place.yaw_deg);
    const glm::dvec3 c = photo.camera.world_to_camera({pose.x_m, 0.0, pose.z_m});
    ax = c.x, az = c.z;
  }
  pose.scale = a.number("--scale", 1.0);
  SL_CHECK(pose.scale > 0 && std::isfinite(pose.scale), "--scale ", pose.scale, " must be positive");
  SunEdit edit;
  if (a.has("--sun-azimuth")) edit.azimuth_deg = a.number("--sun-azimuth", 0);
  if (a.has("--sun-elevation")) edit.elevation_deg = a.number("--sun-elevation", 0);
  edit.intensity_scale = a.number("--sun-intensity", 1.0);
  // --sun-from-shadows (data/sun_from_shadows.h): the photo's own cast shadows and its depth set
  // the sun's direction, and their darkness its strength against the sky; the network keeps the
  // sky's colour and the volume. Without a confident fit the network's sun stays, with a warning.
  const bool from_shadows = a.has("--sun-from-shadows");
  SL_CHECK(!from_shadows || (!a.has("--sun-azimuth") && !a.has("--sun-elevation")),
           "--sun-from-shadows sets the sun's direction itself; drop --sun-azimuth/--sun-elevation");
  SL_CHECK(!from_shadows || photos.size() == 1, "--sun-from-shadows reads one photo's shadows; it does not take ",
           photos.size(), " views");

  const std::string checkpoint = a.has("--checkpoint") ? a.get("--checkpoint") : cli::released_model_path();
  Refinement refine = refinement_from_args(a, checkpoint);
  AtomicDirectory out(a.get("--out"));
  LightingEstimator est(checkpoint);
  configure_estimator(est, a);
  std::vector<InferenceView> views;
  for (const Photo& p : photos) views.push_back({p.ldr, p.depth, p.camera});
  std::optional<ShadowSunLighting> shadow;
  if (from_shadows) {
    shadow = estimate_with_shadow_sun(est, views.front(), edit);
    warn_if_no_shadow_sun(shadow->fit, photo.depth_source, "");
  }
  const EstimatedLighting estimated = shadow ? shadow->lighting : est.estimate(views, edit);
  const PhotoInsertionOptions options = insertion_options(a, est.volume_query());
  SL_CHECK(refine.options.steps == 0 || estimated.has_sky_code, "--refine needs a checkpoint with the 'sky_decoder' "
           "sky branch (a sky vector to refine); '", checkpoint, "' uses '", est.predictor().options().sky_branch, "'");
  RefinementResult refined;
  refined.lighting = estimated;
  PhotoInsertion ins;
  try {
    if (refine.options.steps > 0) {
      refine.options.discriminator_height = est.predictor().options().image_height;  // stage 3's D input size
      refine.options.discriminator_width = est.predictor().options().image_width;
      cli::Progress progress("refine", refine.options.steps);
      refine.options.on_step = [&](int step, double loss) {
        progress.update(step + 1, "-D " + std::to_string(loss));
      };
      PhotoInsertionOptions budget = options;
      budget.aa_samples = refine.aa;
      budget.light_samples = refine.light;
      budget.shadow_rays = refine.shadow;
      refined = refine_lighting(estimated, *est.predictor().sky_decoder(), *refine.discriminator,
                                photo_insertion_inputs(estimated, photo.ldr, photo.depth, photo.camera, object, pose,
                                                       budget),
                                budget, refine.options);
      progress.finish();
    }
    ins = insert_into_photo(refined.lighting, photo.ldr, photo.depth, photo.camera, object, pose, options);
  } catch (const Error& e) {
    fail("--at ", ax, ",", az, " (depth: ", photo.depth_source, "): ", e.what());
  }
  const EstimatedLighting& light = refined.lighting;
  SL_CHECK(ins.visible, "the object at --at ", ax, ",", az, " covers no pixel of the image");

  ImageWriteOptions lin;
  lin.transfer = Transfer::Linear;
  write_image(out.file("composite.png"), ins.composite_ldr, lin);
  if (a.has("--exr")) write_image(out.file("composite.exr"), ins.composite_linear);
  write_image(out.file("object_mask.png"), ins.object_mask, lin);
  write_image(out.file("shadow_map.png"), clamp(ins.shadow_map, 0.0, 1.0), lin);
  const Tensor sky = light.env_world().contiguous();
  write_image(out.file("sky.exr"), sky);
  write_image(out.file("sky.png"), ldr_from_hdr(sky), lin);
  write_depth(out.file("depth.exr"), unsqueeze(photo.depth, 0));
  const std::string label = kitti_label_line("Car", 0.0, 0, ins.box2d, ins.box3d);
  write_text(out.file("label.txt"), label + "\n");
  const glm::dvec3 sun = light.sun_direction_world();
  json j = {{"checkpoint", est.path()},
            {"checkpoint_stage", est.stage()},
            {"checkpoint_step", est.step()},
            {"image", a.has("--sample") ? a.get("--sample") : a.all("--image")[0]},
            {"views", photos.size()},
            {"depth_source", photo.depth_source},
            {"sun", sun_json(light)},
            {"placement", {{"at_camera_ground_xz", {ax, az}},
                           {"world_x_m", pose.x_m},
                           {"world_z_m", pose.z_m},
                           {"ground_y_m", ins.ground_y_m},
                           {"yaw_deg", pose.yaw_deg},
                           {"scale", pose.scale}}},
            {"box2d", ins.box2d},
            {"box3d", {{"h", ins.box3d[0]}, {"w", ins.box3d[1]}, {"l", ins.box3d[2]}, {"x", ins.box3d[3]},
                       {"y", ins.box3d[4]}, {"z", ins.box3d[5]}, {"rotation_y", ins.box3d[6]}}},
            {"kitti_label", label},
            {"timing_ms", {{"lighting", light.inference_ms}, {"insertion", ins.render_ms}}},
            {"insertion", {{"aa", options.aa_samples},
                           {"light_samples", options.light_samples},
                           {"adaptive_samples", options.adaptive_light_samples},
                           {"denoise_radius", options.denoise_radius},
                           {"shadow_rays", options.shadow_rays},
                           {"shadow_map", {options.shadow_width, options.shadow_height}},
                           {"exact_light_rays", options.exact_light_rays},
                           {"exact_shadow_rays", options.shadow_exact_rays},
                           {"radiance_cache", options.radiance_cache}}}};
  j["sun"]["from_sky_vector"] = light.has_sky_code;
  j["sun"]["edited"] = edit.active() || (shadow && shadow->fit.found);
  if (shadow)
    j["sun_from_shadows"] = {{"found", shadow->fit.found},
                             {"azimuth_deg", shadow->fit.azimuth_deg},
                             {"elevation_deg", shadow->fit.elevation_deg},
                             {"score", shadow->fit.score},
                             {"spread_deg", shadow->fit.spread_deg},
                             {"shadow_ratio", shadow->fit.shadow_ratio},
                             {"ground_samples", shadow->fit.ground_samples},
                             {"shadow_samples", shadow->fit.shadow_samples},
                             {"intensity_scale", shadow->intensity_scale},
                             {"ms", shadow->fit.time_ms}};
  if (refine.options.steps > 0) {
    j["refinement"] = {{"steps", refine.options.steps},
                       {"lr", refine.options.lr},
                       {"parameters", refine.options.volume ? json::array({"intensity", "direction", "latent", "volume"})
                                                            : json::array({"intensity", "direction", "latent"})},
                       {"discriminator", refine.discriminator_path},
                       {"discriminator_input", {refine.options.discriminator_height, refine.options.discriminator_width}},
                       {"samples", {{"aa", refine.aa}, {"light", refine.light}, {"shadow", refine.shadow}}},
                       {"loss", "-mean D(composite) at --seed and the refinement's samples, exact volume queries"},
                       {"loss_before", refined.loss_before},
                       {"loss_after", refined.loss_after},
                       {"loss_per_step", refined.loss_per_step},
                       {"skipped_steps", refined.skipped_steps},
                       {"sun_before", sun_json(estimated)},
                       {"sun_after", sun_json(refined.lighting)}};
    j["timing_ms"]["refinement"] = refined.time_ms;
  }
  write_text(out.file("result.json"), j.dump(2) + "\n");
  check_replaceable(a.get("--out"));
  out.commit();
  if (a.has("--json")) std::cout << j.dump() << "\n";
  std::fprintf(stderr, "depth: %s\n", photo.depth_source.c_str());
  if (refine.options.steps > 0) {
    const glm::dvec3 before = estimated.sun_direction_world();
    std::fprintf(stderr, "refine: %d steps, -D %.4f -> %.4f, sun azimuth %.1f° -> %.1f°, elevation %.1f° -> %.1f° (%.0f ms)\n",
                 refine.options.steps, refined.loss_before, refined.loss_after, azimuth_deg_of(before), azimuth_deg_of(sun),
                 elevation_deg_of(before), elevation_deg_of(sun), refined.time_ms);
  }
  std::fprintf(stderr, "wrote %s (sun azimuth %.1f°, elevation %.1f°; lighting %.0f ms, insertion %.0f ms)\n",
               a.get("--out").c_str(), azimuth_deg_of(sun), elevation_deg_of(sun), light.inference_ms, ins.render_ms);
  return 0;
}

// Batch mode (Sec 4.4 augmentation). Inputs: a KITTI-layout folder (image_2/<id>.png with
// calib/<id>.txt, optional label_2/<id>.txt, velodyne/<id>.bin for depth, or depth/<id>.png) or
// a LIST.json of {image, intrinsics, depth?, lidar?, calib?, labels?, id?} (e.g. nuScenes front
// cameras with a per-image intrinsics JSON). Output: a KITTI-layout folder with the same ids.
struct BatchItem {
  std::string id, labels, calib;
  PhotoSources sources;
};

std::vector<BatchItem> batch_items(const std::string& spec, const cli::Args& a) {
  std::vector<BatchItem> out;
  auto base = [&](PhotoSources s) {
    s.camera_height_m = a.number("--camera-height", 1.65);
    s.pitch_deg = a.number("--pitch", 0.0);
    return s;
  };
  if (fs::is_directory(spec)) {
    const fs::path dir(spec);
    SL_CHECK(fs::is_directory(dir / "image_2"), "batch folder '", spec, "' has no image_2/ subfolder");
    std::vector<fs::path> images;
    for (const auto& e : fs::directory_iterator(dir / "image_2"))
      if (e.path().extension() == ".png" || e.path().extension() == ".jpg") images.push_back(e.path());
    std::sort(images.begin(), images.end());
    for (const auto& img : images) {
      BatchItem it;
      it.id = img.stem().string();
      it.calib = (dir / "calib" / (it.id + ".txt")).string();
      SL_CHECK(fs::exists(it.calib), "batch folder '", spec, "': image ", it.id, " has no calib/", it.id, ".txt");
      if (fs::exists(dir / "label_2" / (it.id + ".txt"))) it.labels = (dir / "label_2" / (it.id + ".txt")).string();
      PhotoSources s;
      s.image = img.string();
      s.intrinsics = it.calib;
      if (fs::exists(dir / "depth" / (it.id + ".png"))) {
        s.depth = (dir / "depth" / (it.id + ".png")).string();
      } else if (fs::exists(dir / "velodyne" / (it.id + ".bin"))) {
        s.lidar = (dir / "velodyne" / (it.id + ".bin")).string();
        s.calib = it.calib;
      }
      it.sources = base(s);
      out.push_back(it);
    }
  } else {
    for (const BatchListEntry& entry : read_batch_list(spec)) {
      BatchItem it;
      it.id = entry.id;
      it.labels = entry.labels;
      it.calib = entry.sources.calib;
      it.sources = base(entry.sources);
      out.push_back(it);
    }
  }
  SL_CHECK(!out.empty(), "--batch '", spec, "' lists no images");
  std::set<std::string> ids;
  for (const auto& it : out) SL_CHECK(ids.insert(it.id).second, "--batch '", spec, "': id '", it.id, "' appears twice");
  return out;
}

// The fraction of `box` (x1 y1 x2 y2) covered by mask [H, W] values above 0.5.
double covered_fraction(const std::vector<float>& mask, int W, int H, const std::array<double, 4>& box) {
  const int x0 = std::clamp(int(std::floor(box[0])), 0, W), x1 = std::clamp(int(std::ceil(box[2])), 0, W);
  const int y0 = std::clamp(int(std::floor(box[1])), 0, H), y1 = std::clamp(int(std::ceil(box[3])), 0, H);
  if (x1 <= x0 || y1 <= y0) return 0.0;
  int64_t n = 0;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) n += mask[size_t(y) * W + x] > 0.5f;
  return double(n) / (double(x1 - x0) * (y1 - y0));
}

// Whether a new box's footprint comes within 0.3 m of a labelled object's (input labels and
// objects inserted before). DontCare regions (no 3D box) do not count.
bool overlaps_any(const std::array<double, 7>& b, const std::vector<KittiLabel>& a, const std::vector<KittiLabel>& c) {
  for (const auto* list : {&a, &c})
    for (const KittiLabel& l : *list)
      if (l.box3d[1] > 0 && l.box3d[2] > 0 && l.box3d[5] > -100 && footprints_within(b, l.box3d, 0.3)) return true;
  return false;
}

// Test hook: STREETLIGHT_INSERT_KILL_AFTER=k kills the process (SIGKILL) after k images, in the
// middle of image k + 1 with its files written under temporary names: what a kill can leave.
int kill_after() {
  const char* v = std::getenv("STREETLIGHT_INSERT_KILL_AFTER");
  return v ? std::atoi(v) : -1;
}

struct BatchResult {
  int placed = 0;
  std::string depth_source;
  std::optional<bool> sun_from_shadows;  // with --sun-from-shadows: whether the fit was used
};

BatchResult augment_one(const cli::Args& a, LightingEstimator& est, const std::vector<Mesh>& objects,
                        const BatchItem& item, uint64_t item_index, const fs::path& out, int done_so_far) {
  Photo photo = load_photo(item.sources);
  std::vector<KittiLabel> labels = item.labels.empty() ? std::vector<KittiLabel>{} : read_kitti_labels(item.labels);
  const std::string calib = item.calib.empty() ? kitti_calibration_from_intrinsics(photo.camera.intrinsics())
                                               : kitti_calibration_text(item.calib);
  std::optional<ShadowSunLighting> shadow;
  if (a.has("--sun-from-shadows")) {
    shadow = estimate_with_shadow_sun(est, {photo.ldr, photo.depth, photo.camera});
    warn_if_no_shadow_sun(shadow->fit, photo.depth_source, item.id);
  }
  const EstimatedLighting light = shadow ? shadow->lighting : est.estimate({{photo.ldr, photo.depth, photo.camera}});
  const int per_image = static_cast<int>(a.integer("--objects-per-image", 1));
  const uint64_t seed = static_cast<uint64_t>(a.integer("--seed", 0));
  const Intrinsics& k = photo.camera.intrinsics();
  std::vector<float> inserted(size_t(k.width) * k.height, 0.0f);  // union of the inserted objects' masks
  std::vector<KittiLabel> added;
  Rng rng(seed, item_index);
  BatchResult res;
  res.depth_source = photo.depth_source;
  if (shadow) res.sun_from_shadows = shadow->fit.found;
  for (int attempt = 0; attempt < 40 * per_image && res.placed < per_image; ++attempt) {
    // A random spot on the road ahead: 6-25 m forward, within ±4 m of the centre line.
    Placement pose;
    pose.x_m = rng.uniform(-4.0, 4.0);
    pose.z_m = -rng.uniform(6.0, 25.0);
    pose.yaw_deg = rng.uniform(0.0, 360.0);
    const Mesh& obj = objects[static_cast<size_t>(rng.randint(static_cast<int64_t>(objects.size())))];
    if (overlaps_any(kitti_box3d(obj, pose, photo.camera), labels, added)) continue;  // never park in a real car
    PhotoInsertion ins;
    try {
      PhotoInsertionOptions o = insertion_options(a, est.volume_query());
      o.seed = hash_counter(seed, item_index, static_cast<uint64_t>(attempt));
      ins = insert_into_photo(light, photo.ldr, photo.depth, photo.camera, obj, pose, o);
    } catch (const Error&) {
      continue;  // not on the ground / outside the view: draw another spot
    }
    if (!ins.visible) continue;
    photo.ldr = ins.composite_ldr;  // later objects go into the augmented photo...
    const float* m = ins.object_mask.data<float>();
    const float* z = ins.object_depth.data<float>();
    float* d = photo.depth.data<float>();
    for (size_t p = 0; p < inserted.size(); ++p)
      if (m[p] > 0.5f) {
        inserted[p] = 1.0f;
        d[p] = z[p];  // ...and stand in front of what they cover
      }
    KittiLabel l;
    l.type = "Car";
    l.box2d = ins.box2d;
    l.box3d = ins.box3d;
    l.truncated = ins.truncated;
    l.occluded = occlusion_level(ins.hidden_fraction);
    l.alpha = std::remainder(ins.box3d[6] - std::atan2(ins.box3d[3], ins.box3d[5]), 2 * kPi);
    const std::vector<float> this_mask(m, m + inserted.size());
    for (KittiLabel& prev : added) cover_label(prev, covered_fraction(this_mask, k.width, k.height, prev.box2d));
    added.push_back(l);
    ++res.placed;
  }
  for (KittiLabel& l : labels) cover_label(l, covered_fraction(inserted, k.width, k.height, l.box2d));
  std::string text;
  for (const auto* list : {&labels, &added})
    for (const KittiLabel& l : *list) text += format_kitti_label(l) + "\n";
  // Image last: its presence marks the frame finished (resume skips it).
  const std::string label_path = (out / "label_2" / (item.id + ".txt")).string();
  const std::string calib_path = (out / "calib" / (item.id + ".txt")).string();
  const std::string image_path = (out / "image_2" / (item.id + ".png")).string();
  AtomicFile label_file(label_path), calib_file(calib_path);
  label_file.write(text.data(), text.size());
  calib_file.write(calib.data(), calib.size());
  if (kill_after() == done_so_far) std::raise(SIGKILL);
  label_file.commit();
  calib_file.commit();
  ImageWriteOptions lin;
  lin.transfer = Transfer::Linear;
  write_image(image_path, photo.ldr, lin);
  return res;
}

int batch(const cli::Args& a) {
  SL_CHECK(a.has("--out"), "--batch needs --out DIR");
  const std::vector<BatchItem> items = batch_items(a.get("--batch"), a);
  const std::vector<std::string> specs = a.has("--object") ? a.all("--object") : std::vector<std::string>{"procedural:car"};
  std::vector<Mesh> objects;
  for (const auto& s : specs) objects.push_back(load_object(s));
  // The output folder is written in place, frame by frame, so that a run can resume: batch.json
  // marks it as this tool's, a frame is finished when its image exists (written last), and
  // leftovers of a killed run (util/file.h temporaries of a process that is gone) are removed first.
  const fs::path out(a.get("--out"));
  const json marker = {{"tool", "streetlight-insert --batch"}, {"input", fs::absolute(a.get("--batch")).string()}};
  if (fs::exists(out)) {
    SL_CHECK(fs::is_directory(out), "--out '", out.string(), "' exists and is not a folder");
    if (fs::exists(out / "batch.json")) {
      std::ifstream f(out / "batch.json");
      json prev;
      try {
        prev = json::parse(f);
      } catch (const std::exception&) {
      }
      SL_CHECK(prev.value("input", "") == marker["input"], "--out '", out.string(), "' holds a batch of another input ('",
               prev.value("input", "?"), "'); choose another folder");
    } else {
      SL_CHECK(fs::is_empty(out), "--out '", out.string(), "' exists and is not a streetlight-insert batch; choose another folder");
    }
  }
  LightingEstimator est(a.has("--checkpoint") ? a.get("--checkpoint") : cli::released_model_path());
  configure_estimator(est, a);
  for (const char* d : {"image_2", "label_2", "calib"}) fs::create_directories(out / d);
  write_file_atomic((out / "batch.json").string(), marker.dump(2) + "\n");
  for (const char* d : {"image_2", "label_2", "calib"}) sweep_stale_temp_files((out / d).string());
  std::vector<size_t> todo;
  for (size_t i = 0; i < items.size(); ++i)
    if (!fs::exists(out / "image_2" / (items[i].id + ".png"))) todo.push_back(i);
  if (todo.size() < items.size())
    std::fprintf(stderr, "resuming: %zu of %zu images already finished\n", items.size() - todo.size(), items.size());
  cli::Progress progress("insert", static_cast<int64_t>(todo.size()));
  int done = 0, placed = 0;
  json this_run = json::array();
  for (size_t i : todo) {
    const BatchResult r = augment_one(a, est, objects, items[i], i, out, done);
    placed += r.placed;
    this_run.push_back({{"id", items[i].id}, {"objects", r.placed}, {"depth", r.depth_source}});
    if (r.sun_from_shadows) this_run.back()["sun_from_shadows"] = *r.sun_from_shadows;
    progress.update(++done, items[i].id);
  }
  progress.finish();
  std::vector<std::string> ids;
  for (const auto& it : items) ids.push_back(it.id);
  const json summary = {{"images", items.size()}, {"objects_this_run", placed}, {"ids", ids}, {"this_run", this_run}};
  write_file_atomic((out / "result.json").string(), summary.dump(2) + "\n");
  if (a.has("--json")) std::cout << summary.dump() << "\n";
  std::fprintf(stderr, "wrote %zu images to %s (%d this run)\n", items.size(), out.string().c_str(), done);
  return 0;
}

int run(int argc, char** argv) {
  cli::Args a("streetlight-insert",
              "streetlight-insert --image PHOTO --intrinsics FILE --object MODEL.glb --at X,Z [--yaw DEG] [--scale S]\n"
              "                   [--checkpoint CKPT] --out DIR [--depth FILE | --lidar BIN --calib FILE]\n"
              "                   [--refine N [--discriminator FILE]]\n"
              "streetlight-insert --batch LIST.json|FOLDER [--checkpoint CKPT] --out DIR [--object M.glb ...]\n\n"
              "Estimates the photo's HDR lighting with a trained checkpoint (Wang et al. ECCV 2022, Sec 3.2) and\n"
              "inserts a glTF object with its shading and cast shadow (Sec 3.3). --at X,Z is in metres in the first\n"
              "camera's ground frame: X to the right, Z forward. Depth: --depth, else --lidar + --calib, else the\n"
              "ground plane seen from --camera-height and --pitch. --object procedural:car needs no file.",
              {{"--image", "PHOTO", "street photo (PNG/JPEG; several for multi-view, with --pose)", true},
               {"--intrinsics", "FILE", "KITTI 3x4 projection file (P2) or JSON {fx, fy, cx, cy}", true},
               {"--sample", "DIR", "a generated street sample (DIR/samples/<id>): view 0 with its depth and pose;\n"
                "                               without --at, the generator's own placement"},
               {"--pose", "X,Y,Z,YAW[,PITCH]", "multi-view: world pose of each camera (metres, degrees)", true},
               {"--depth", "FILE", "metric depth: EXR (metres) or KITTI 16-bit PNG (metres*256)"},
               {"--lidar", "BIN", "KITTI velodyne .bin, projected and densified (needs --calib)"},
               {"--calib", "FILE", "KITTI calibration (text or mmdetection3d JSON) for --lidar"},
               {"--camera-height", "M", "camera height above the ground (default 1.65)"},
               {"--pitch", "DEG", "camera pitch, positive up (default 0)"},
               {"--object", "MODEL", "glTF/GLB model, or procedural:car (several: batch mode only)", true},
               {"--at", "X,Z", "ground position in metres (right, forward) of the first camera"},
               {"--yaw", "DEG", "object heading about +Y; 90 points its length away from the camera (default 90)"},
               {"--scale", "S", "uniform object scale (default 1)"},
               {"--checkpoint", "CKPT", "lighting or adversarial stage checkpoint (default: the released model, models/streetlight.safetensors)"},
               {"--out", "DIR", "output folder (written atomically)"},
               {"--no-flip-average", "", "take the sun from one pass of the network instead of averaging it with the\n"
                                         "mirrored photo's (saves one backbone pass)"},
               {"--crop-scales", "LIST", "centred crops whose suns are averaged with the photo's, as fractions of its size\n"
                "                               (default none: off; e.g. 0.55,0.7,0.85, docs/RESULTS.md; result.json\n"
                "                               sun.crop_spread_deg is the largest angle between the photo's sun and a crop's)"},
               {"--no-visible-sun", "", "keep the network's sun even where the photo shows the sun disk (by default a\n"
                "                               visible sun sets the direction, data/visible_sun.h; result.json sun.visible_sun)"},
               {"--exr", "", "also write the composite as linear EXR"},
               {"--sun-azimuth", "DEG", "edit the sun: world azimuth (Sec 3.2 sky vector)"},
               {"--sun-elevation", "DEG", "edit the sun: elevation above the horizon"},
               {"--sun-intensity", "X", "edit the sun: multiply its intensity by X"},
               {"--sun-from-shadows", "", "set the sun's direction and strength from the photo's own cast shadows and its\n"
                "                               depth (needs real geometry: --lidar or --depth); else the network's sun stays"},
               {"--aa", "N", "primary rays per pixel (default 4)"},
               {"--light-samples", "N", "light samples per primary ray, Eq. 2 (default 8)"},
               {"--adaptive-samples", "X", "on average X more per primary ray where the neighbouring pixels were noisy\n"
                "                               (default 2; 0: off)"},
               {"--denoise-radius", "N", "smooth the sampled part of Eq. 2 over (2N+1)^2 pixels, guided by normals, depth\n"
                "                               and its own noise (default 2; 0: off)"},
               {"--shadow-rays", "N", "shadow rays per shadow-map pixel, Eq. 4 (default 256)"},
               {"--exact-light-rays", "M", "of each primary ray's light samples, M also marched exactly to correct the\n"
                "                               radiance cache's bias (default 2; 0: off)"},
               {"--exact-shadow-rays", "M", "the same for the shadow rays of each shadow-map pixel (default 16; 0: off)"},
               {"--fast", "", "the settings before the exact corrections: --light-samples 6 --shadow-rays 128\n"
                "                               --exact-light-rays 0 --exact-shadow-rays 0 (about half the time; KITTI:\n"
                "                               1.2-1.6% error against 0.9%); flags given explicitly still win"},
               {"--shadow-width", "N", "shadow-map width (default 160)"},
               {"--shadow-height", "N", "shadow-map height (default 90)"},
               {"--seed", "N", "sampling seed (default 0)"},
               {"--exact", "", "march the volume for every light/shadow ray instead of the radiance cache (slower)"},
               {"--refine", "N", "paper Fig. 7: N Adam steps on the sky vector (intensity, direction, latent) that\n"
                "                               lower -D of the stage-3 discriminator on the composite (default 0: off)"},
               {"--refine-lr", "LR", "Adam step size of --refine (default 0.05)"},
               {"--refine-volume", "", "--refine also optimises the VSG volume"},
               {"--refine-samples", "A,L,S", "--refine's renders: primary rays per pixel, light samples, shadow rays (default\n"
                "                               1,4,16; exact volume queries, so far costlier per ray than the final render)"},
               {"--discriminator", "FILE", "the discriminator for --refine: a stage-3 checkpoint or an export made with\n"
                "                               --with-discriminator (default: the one in --checkpoint, if any)"},
               {"--batch", "LIST", "batch mode: KITTI folder (image_2, calib, label_2, velodyne) or JSON list of\n"
                "                               {image, intrinsics, depth|lidar+calib, labels, id}; writes a KITTI folder\n"
                "                               keeping ids, labels and calibration, and resumes a killed run"},
               {"--objects-per-image", "N", "batch: objects per image (default 1)"},
               {"--json", "", "print result.json on stdout"}});
  if (!a.parse(argc, argv)) return 0;
  SL_CHECK(!a.has("--batch") || a.integer("--refine", 0) == 0, "--refine works on one image; it is not available with --batch");
  return a.has("--batch") ? batch(a) : single(a);
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
