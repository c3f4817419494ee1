// streetlight-insert: inserts a glTF object into a street photo with the lighting a trained
// checkpoint estimates from the photo (Sec 3.2-3.3), or, in batch mode, random objects into
// many photos, writing an augmented dataset in KITTI layout (Sec 4.4).
//
// Outputs (single image) in --out DIR, written to a temporary sibling folder first and renamed
// only when everything succeeded, so bad input leaves nothing behind:
//   composite.png (+ composite.exr with --exr), object_mask.png, shadow_map.png, sky.exr,
//   sky.png (tone-mapped, world azimuths), depth.exr (the depth used), result.json (sun, with
//   flip_spread_deg, hedge and crop_spread_deg: the network's confidences, train/inference.h
//   sun_flip_spread_deg, sun_hedge and sun_crop_spread_deg (smaller is more confident for all),
//   probability: train/inference.h sun_probability (models with a sun head; larger is more confident), and
//   visible_sun: whether a sun disk in the photo set the direction, and its pixel; placement,
//   boxes, KITTI label line, timings; with --refine N > 0 the discriminator loss and the sun
//   before and after refinement), label.txt (the KITTI line).
// --refine N (paper Fig. 7): N Adam steps on the sky vector (and with --refine-volume the volume)
// against the stage-3 discriminator, train/lighting_refinement.h; the composite then uses the
// refined lighting. N = 0 (the default) changes nothing.
// Batch mode writes a KITTI folder in place, frame by frame, and resumes (tools/common/insert_batch.h).
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
#include "tools/common/insert_batch.h"
#include "tools/common/insert_options.h"
#include "train/batch_list.h"
#include "train/inference.h"
#include "train/lighting_refinement.h"
#include "train/losses.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"
#include "util/file.h"
#include "util/math.h"
#include "util/random.h"

using sl::data::ImageWriteOptions;
using sl::train::estimate_with_shadow_sun;
using sl::train::ShadowSunLighting;
using sl::data::Transfer;
using sl::data::write_depth;
using sl::data::write_image;
using sl::render::Mesh;
using sl::render::Placement;
using sl::train::street_sample_object;

namespace fs = std::filesystem;
using nlohmann::json;
using namespace sl;
using namespace sl::train;
using sl::cli::configure_estimator;
using sl::cli::insertion_options;
using sl::cli::load_object;
using sl::cli::note_if_sun_is_a_guess;
using sl::cli::warn_if_no_shadow_sun;

namespace {

std::pair<double, double> parse_pair(const std::string& flag, const std::string& v, const char* shape = "X,Z") {
  double a = 0, b = 0;
  char comma = 0, extra = 0;
  std::istringstream is(v);
  if (!(is >> a >> comma >> b) || comma != ',' || (is >> extra) || !std::isfinite(a) || !std::isfinite(b))
    fail(flag, " expects two numbers '", shape, "', got '", v, "'");
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
          {"pixel", {light.visible_sun_pixel.x, light.visible_sun_pixel.y}}, {"score", light.visible_sun_score},
          {"learned", light.visible_sun_learned}};
}

// The third confidence, from crop averaging (train/inference.h sun_crop_spread_deg), null when off.
json crop_spread_json(const EstimatedLighting& light) {
  return std::isfinite(light.sun_crop_spread_deg) ? json(light.sun_crop_spread_deg) : json();
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
          {"probability", std::isfinite(light.sun_probability) ? json(light.sun_probability) : json()},
          {"visible_sun", visible_sun_json(light)},
          {"glare_azimuth_used", light.glare_azimuth_used}};
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

// The first view's intrinsics and where they came from (train/photo_input.h photo_intrinsics).
json intrinsics_json(const Photo& photo) {
  const render::Intrinsics& k = photo.camera.intrinsics();
  return {{"source", photo.intrinsics_source}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}};
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
  if (a.has("--fov")) {
    s.fov_deg = a.number("--fov", 0.0);
    SL_CHECK(std::isfinite(s.fov_deg) && s.fov_deg > 0.0 && s.fov_deg < 180.0,
             "--fov DEG must lie between 0 and 180 degrees, got ", a.get("--fov"));
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
  SL_CHECK(a.has("--object") || a.has("--sample"), "--object MODEL.glb is required (or procedural:car)");
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
  // A sample is compared with its path-traced truth, so by default it gets the generator's object.
  const std::string object_spec = a.has("--object") ? a.get("--object") : street_sample_object(a.get("--sample"));
  const Mesh object = load_object(object_spec);
  const std::string object_class = cli::object_classes(a, 1)[0];
  SL_CHECK(a.has("--at") || a.has("--at-pixel") || has_sample_place,
           "--at X,Z is required (metres right of and ahead of the first camera), or --at-pixel U,V");
  SL_CHECK(!(a.has("--at") && a.has("--at-pixel")), "give --at X,Z or --at-pixel U,V, not both");
  Placement pose;
  pose.yaw_deg = 90.0;
  double ax = 0, az = 0;
  if (a.has("--at-pixel")) {
    // The object stands on what the first photo shows at that pixel (its depth: file, lidar or
    // the ground plane).
    const auto [u, v] = parse_pair("--at-pixel", a.get("--at-pixel"), "U,V");
    try {
      const render::PixelPlacement at = render::placement_at_pixel(
          photo.camera, photo.depth, static_cast<int>(std::floor(u)), static_cast<int>(std::floor(v)),
          a.number("--yaw", 90.0));
      pose = at.placement;
      ax = at.right_m, az = at.forward_m;
    } catch (const Error& e) {
      fail("--at-pixel ", a.get("--at-pixel"), " (depth: ", photo.depth_source, "): ", e.what());
    }
  } else if (a.has("--at")) {
    std::tie(ax, az) = parse_pair("--at", a.get("--at"));
    // --at is in the first camera's ground frame: X right, Z forward.
    pose = render::placement_in_camera_ground_frame(photo.camera, ax, az, a.number("--yaw", 90.0));
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
  const std::string label = kitti_label_line(object_class, 0.0, 0, ins.box2d, ins.box3d);
  write_text(out.file("label.txt"), label + "\n");
  const glm::dvec3 sun = light.sun_direction_world();
  json j = {{"checkpoint", est.path()},
            {"checkpoint_stage", est.stage()},
            {"checkpoint_step", est.step()},
            {"image", a.has("--sample") ? a.get("--sample") : a.all("--image")[0]},
            {"views", photos.size()},
            {"object", object_spec},
            {"class", object_class},
            {"depth_source", photo.depth_source},
            {"intrinsics", intrinsics_json(photo)},
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
  if (photo.intrinsics_source == "fov" || photo.intrinsics_source == "exif")
    std::fprintf(stderr, "intrinsics: from %s, fx = fy = %.1f px (horizontal field of view %.1f°)\n",
                 photo.intrinsics_source == "fov" ? "--fov" : "the photo's EXIF 35 mm-equivalent focal length",
                 photo.camera.intrinsics().fx,
                 2.0 * std::atan(0.5 * photo.camera.intrinsics().width / photo.camera.intrinsics().fx) * 180.0 / kPi);
  if (refine.options.steps > 0) {
    const glm::dvec3 before = estimated.sun_direction_world();
    std::fprintf(stderr, "refine: %d steps, -D %.4f -> %.4f, sun azimuth %.1f° -> %.1f°, elevation %.1f° -> %.1f° (%.0f ms)\n",
                 refine.options.steps, refined.loss_before, refined.loss_after, azimuth_deg_of(before), azimuth_deg_of(sun),
                 elevation_deg_of(before), elevation_deg_of(sun), refined.time_ms);
  }
  std::fprintf(stderr, "wrote %s (sun azimuth %.1f°, elevation %.1f°; lighting %.0f ms, insertion %.0f ms)\n",
               a.get("--out").c_str(), azimuth_deg_of(sun), elevation_deg_of(sun), light.inference_ms, ins.render_ms);
  if (!edit.azimuth_deg && !edit.elevation_deg && !(shadow && shadow->fit.found) && !light.visible_sun_found &&
      refine.options.steps == 0)
    note_if_sun_is_a_guess(light.sun_probability, photo.depth_source);
  return 0;
}

int run(int argc, char** argv) {
  cli::Args a("streetlight-insert",
              "streetlight-insert --image PHOTO [--intrinsics FILE | --fov DEG] --object MODEL.glb --at X,Z [--yaw DEG]\n"
              "                   [--scale S] [--checkpoint CKPT] --out DIR [--depth FILE | --lidar BIN --calib FILE]\n"
              "                   [--refine N [--discriminator FILE]]\n"
              "streetlight-insert --batch LIST.json|FOLDER [--checkpoint CKPT] --out DIR [--object M.glb ...]\n\n"
              "Estimates the photo's HDR lighting with a trained checkpoint (Wang et al. ECCV 2022, Sec 3.2) and\n"
              "inserts a glTF object with its shading and cast shadow (Sec 3.3). --at X,Z is in metres in the first\n"
              "camera's ground frame: X to the right, Z forward. Depth: --depth, else --lidar + --calib, else the\n"
              "ground plane seen from --camera-height and --pitch. Intrinsics: --intrinsics, else --calib, else\n"
              "--fov, else the photo's EXIF 35 mm-equivalent focal length (phone and camera JPEGs have it); a\n"
              "photo's EXIF orientation is applied. --object procedural:car needs no file.",
              {{"--image", "PHOTO", "street photo (PNG/JPEG; several for multi-view, with --pose)", true},
               {"--intrinsics", "FILE", "KITTI 3x4 projection file (P2) or JSON {fx, fy, cx, cy}", true},
               {"--fov", "DEG", "horizontal field of view, for a photo without --intrinsics (centred, square pixels)"},
               {"--sample", "DIR", "a generated street sample (DIR/samples/<id>): view 0 with its depth and pose;\n"
                "                               without --at, the generator's own placement; without --object, its object"},
               {"--pose", "X,Y,Z,YAW[,PITCH]", "multi-view: world pose of each camera (metres, degrees)", true},
               {"--depth", "FILE", "metric depth: EXR (metres) or KITTI 16-bit PNG (metres*256)"},
               {"--lidar", "BIN", "KITTI velodyne .bin, projected and densified (needs --calib)"},
               {"--calib", "FILE", "KITTI calibration (text or mmdetection3d JSON) for --lidar"},
               {"--camera-height", "M", "camera height above the ground (default 1.65)"},
               {"--pitch", "DEG", "camera pitch, positive up (default 0)"},
               {"--object", "MODEL", "glTF/GLB model, or procedural:car (several: batch mode only)", true},
               {"--class", "NAME", "the object's KITTI class in label.txt: Car (default), Van, Truck, Pedestrian,\n"
                "                               Person_sitting, Cyclist, Tram or Misc (batch: once, or once per --object)", true},
               {"--at", "X,Z", "ground position in metres (right, forward) of the first camera"},
               {"--at-pixel", "U,V", "instead of --at: stand the object on what the first photo shows at pixel column U,\n"
                "                               row V (pick a pixel on the ground; result.json gives its --at X,Z)"},
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
               {"--sun-glare", "FILE", "the learned sun-glare detector behind the disk test (default: the released one,\n"
                "                               models/sun_glare.safetensors, when present; train/sun_glare.h)"},
               {"--no-sun-glare", "", "the disk test alone finds a visible sun"},
               {"--exr", "", "also write the composite as linear EXR"},
               {"--sun-azimuth", "DEG", "edit the sun: world azimuth (Sec 3.2 sky vector)"},
               {"--sun-elevation", "DEG", "edit the sun: elevation above the horizon"},
               {"--sun-intensity", "X", "edit the sun: multiply its intensity by X"},
               {"--sun-from-shadows", "", "set the sun's direction and strength from the photo's own cast shadows and its\n"
                "                               depth (needs real geometry: --lidar or --depth); else the network's sun stays"},
               {"--aa", "N", "primary rays per pixel (default 4)"},
               {"--light-samples", "N", "light samples per primary ray, Eq. 2 (default 16)"},
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
               {"--batch", "LIST", "batch mode: KITTI folder (image_2, calib, label_2, velodyne), a folder of photos\n"
                "                               (intrinsics from --fov or their EXIF), or JSON list of {image,\n"
                "                               intrinsics|fov, depth|lidar+calib, labels, id}; writes a KITTI folder\n"
                "                               keeping ids, labels and calibration, and resumes a killed run"},
               {"--objects-per-image", "N", "batch: objects per image (default 1)"},
               {"--json", "", "print result.json on stdout"}});
  if (!a.parse(argc, argv)) return 0;
  SL_CHECK(!a.has("--batch") || a.integer("--refine", 0) == 0, "--refine works on one image; it is not available with --batch");
  return a.has("--batch") ? cli::insert_batch(a) : single(a);
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
