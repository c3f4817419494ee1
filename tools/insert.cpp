// streetlight-insert: inserts a glTF object into a street photo with the lighting a trained
// checkpoint estimates from the photo (Sec 3.2-3.3), or, in batch mode, random objects into
// many photos, writing an augmented dataset in KITTI layout (Sec 4.4).
//
// Outputs (single image) in --out DIR, written to a temporary sibling folder first and renamed
// only when everything succeeded, so bad input leaves nothing behind:
//   composite.png (+ composite.exr with --exr), object_mask.png, shadow_map.png, sky.exr,
//   sky.png (tone-mapped, world azimuths), depth.exr (the depth used), result.json (sun, placement,
//   boxes, KITTI label line, timings), label.txt (the KITTI line).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "autodiff/random.h"
#include "data/image_io.h"
#include "data/procedural_car.h"
#include "render/gltf_loader.h"
#include "tools/common/cli.h"
#include "train/batch_list.h"
#include "train/inference.h"
#include "train/losses.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"

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
  if (spec == "procedural:car") return to_object_frame_mesh(make_procedural_car());
  SL_CHECK(fs::exists(spec), "object file '", spec, "' does not exist");
  return to_object_frame_mesh(load_gltf(spec));
}

// A temporary sibling of `out`, renamed over it by commit(); removed on destruction otherwise.
class StagingDir {
 public:
  explicit StagingDir(const std::string& out) : out_(out) {
    const fs::path parent = fs::absolute(out).parent_path();
    fs::create_directories(parent);
    tmp_ = parent / ("." + fs::path(out).filename().string() + ".tmp-" + std::to_string(::getpid()));
    fs::remove_all(tmp_);
    fs::create_directories(tmp_);
  }
  ~StagingDir() {
    std::error_code ec;
    if (!committed_) fs::remove_all(tmp_, ec);
  }
  std::string path(const std::string& name) const { return (tmp_ / name).string(); }
  void commit() {
    if (fs::exists(out_)) {
      SL_CHECK(fs::is_directory(out_) && (fs::is_empty(out_) || fs::exists(fs::path(out_) / "result.json") ||
                                          fs::exists(fs::path(out_) / "image_2")),
               "--out '", out_, "' exists and is not a previous streetlight-insert output; choose another folder");
      fs::remove_all(out_);
    }
    fs::rename(tmp_, out_);
    committed_ = true;
  }

 private:
  std::string out_;
  fs::path tmp_;
  bool committed_ = false;
};

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
  SL_CHECK(f.good(), "cannot write '", path, "'");
}

PhotoInsertionOptions insertion_options(const cli::Args& a, int volume_samples) {
  PhotoInsertionOptions o;
  o.aa_samples = static_cast<int>(a.integer("--aa", 4));
  o.light_samples = static_cast<int>(a.integer("--light-samples", 64));
  o.shadow_rays = static_cast<int>(a.integer("--shadow-rays", 128));
  o.shadow_width = static_cast<int>(a.integer("--shadow-width", 160));
  o.shadow_height = static_cast<int>(a.integer("--shadow-height", 90));
  o.seed = static_cast<uint64_t>(a.integer("--seed", 0));
  o.volume_samples = volume_samples;
  SL_CHECK(o.aa_samples > 0 && o.light_samples > 0 && o.shadow_rays > 0 && o.shadow_width > 0 && o.shadow_height > 0,
           "--aa, --light-samples, --shadow-rays, --shadow-width and --shadow-height must be positive");
  return o;
}

json vec_json(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

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
  StreetPlacement sample_place;
  bool has_sample_place = false;
  if (a.has("--sample")) {
    photos.push_back(load_street_view(a.get("--sample"), 0, &sample_place, &has_sample_place));
  } else {
    for (size_t i = 0; i < a.all("--image").size(); ++i) photos.push_back(load_photo(sources_from_args(a, i)));
  }
  const Photo& photo = photos[0];
  const Mesh object = load_object(a.get("--object"));
  SL_CHECK(a.has("--at") || has_sample_place, "--at X,Z is required (metres right of and ahead of the first camera)");
  ObjectPose pose;
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

  StagingDir out(a.get("--out"));
  LightingEstimator est(a.has("--checkpoint") ? a.get("--checkpoint") : cli::released_model_path());
  std::vector<InferenceView> views;
  for (const Photo& p : photos) views.push_back({p.ldr, p.depth, p.camera});
  const EstimatedLighting light = est.estimate(views, edit);
  PhotoInsertion ins;
  try {
    ins = insert_into_photo(light, photo.ldr, photo.depth, photo.camera, object, pose,
                            insertion_options(a, est.volume_samples()));
  } catch (const Error& e) {
    fail("--at ", ax, ",", az, " (depth: ", photo.depth_source, "): ", e.what());
  }
  SL_CHECK(ins.visible, "the object at --at ", ax, ",", az, " covers no pixel of the image");

  ImageWriteOptions lin;
  lin.transfer = Transfer::Linear;
  write_image(out.path("composite.png"), ins.composite_ldr, lin);
  if (a.has("--exr")) write_image(out.path("composite.exr"), ins.composite_linear);
  write_image(out.path("object_mask.png"), ins.object_mask, lin);
  write_image(out.path("shadow_map.png"), clamp(ins.shadow_map, 0.0, 1.0), lin);
  const Tensor sky = light.env_world().contiguous();
  write_image(out.path("sky.exr"), sky);
  write_image(out.path("sky.png"), ldr_from_hdr(sky), lin);
  write_depth(out.path("depth.exr"), unsqueeze(photo.depth, 0));
  const std::string label = kitti_label_line("Car", 0.0, 0, ins.box2d, ins.box3d);
  write_text(out.path("label.txt"), label + "\n");
  const glm::dvec3 sun = light.sun_direction_world();
  json j = {{"checkpoint", est.path()},
            {"checkpoint_stage", est.stage()},
            {"checkpoint_step", est.step()},
            {"image", a.has("--sample") ? a.get("--sample") : a.all("--image")[0]},
            {"views", photos.size()},
            {"depth_source", photo.depth_source},
            {"sun", {{"direction_world", vec_json(sun)},
                     {"azimuth_deg", azimuth_deg_of(sun)},
                     {"elevation_deg", elevation_deg_of(sun)},
                     {"intensity_rgb", vec_json(light.sun_intensity_rgb)},
                     {"from_sky_vector", light.has_sky_code},
                     {"edited", edit.active()}}},
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
            {"timing_ms", {{"lighting", light.inference_ms}, {"insertion", ins.render_ms}}}};
  write_text(out.path("result.json"), j.dump(2) + "\n");
  out.commit();
  if (a.has("--json")) std::cout << j.dump() << "\n";
  std::fprintf(stderr, "depth: %s\n", photo.depth_source.c_str());
  std::fprintf(stderr, "wrote %s (sun azimuth %.1f°, elevation %.1f°; lighting %.0f ms, insertion %.0f ms)\n",
               a.get("--out").c_str(), azimuth_deg_of(sun), elevation_deg_of(sun), light.inference_ms, ins.render_ms);
  return 0;
}

// Batch mode: a LIST.json ([{image, intrinsics, depth?, lidar?, calib?}, ...]) or a KITTI-style
// folder (image_2/*.png with calib/<id>.txt, optional velodyne/<id>.bin or depth/<id>.png).
std::vector<PhotoSources> batch_sources(const std::string& spec, const cli::Args& a) {
  std::vector<PhotoSources> out;
  auto base = [&](PhotoSources s) {
    s.camera_height_m = a.number("--camera-height", 1.65);
    s.pitch_deg = a.number("--pitch", 0.0);
    return s;
  };
  if (fs::is_directory(spec)) {
    const fs::path dir(spec);
    SL_CHECK(fs::is_directory(dir / "image_2"), "batch folder '", spec, "' has no image_2/ subfolder");
    std::vector<fs::path> images;
    for (const auto& e : fs::directory_iterator(dir / "image_2")) images.push_back(e.path());
    std::sort(images.begin(), images.end());
    for (const auto& img : images) {
      const std::string id = img.stem().string();
      PhotoSources s;
      s.image = img.string();
      s.intrinsics = (dir / "calib" / (id + ".txt")).string();
      if (fs::exists(dir / "depth" / (id + ".png"))) s.depth = (dir / "depth" / (id + ".png")).string();
      out.push_back(base(s));
    }
  } else {
    for (const PhotoSources& s : read_batch_list(spec)) out.push_back(base(s));
  }
  SL_CHECK(!out.empty(), "--batch '", spec, "' lists no images");
  return out;
}

int batch(const cli::Args& a) {
  SL_CHECK(a.has("--out"), "--batch needs --out DIR");
  const std::vector<PhotoSources> sources = batch_sources(a.get("--batch"), a);
  const std::vector<std::string> specs = a.has("--object") ? a.all("--object") : std::vector<std::string>{"procedural:car"};
  std::vector<Mesh> objects;
  for (const auto& s : specs) objects.push_back(load_object(s));
  const int per_image = static_cast<int>(a.integer("--objects-per-image", 1));
  const uint64_t seed = static_cast<uint64_t>(a.integer("--seed", 0));
  StagingDir out(a.get("--out"));
  for (const char* d : {"image_2", "label_2", "calib"}) fs::create_directories(out.path(d));
  LightingEstimator est(a.has("--checkpoint") ? a.get("--checkpoint") : cli::released_model_path());
  cli::Progress progress("insert", static_cast<int64_t>(sources.size()));
  json manifest = json::array();
  for (size_t i = 0; i < sources.size(); ++i) {
    Photo photo = load_photo(sources[i]);
    const EstimatedLighting light = est.estimate({{photo.ldr, photo.depth, photo.camera}});
    std::vector<std::string> labels;
    Rng rng(seed, i);
    int placed = 0;
    for (int attempt = 0; attempt < 40 * per_image && placed < per_image; ++attempt) {
      // A random spot on the road ahead: 6-25 m forward, within ±3 m of the centre line.
      ObjectPose pose;
      pose.x_m = rng.uniform(-3.0, 3.0);
      pose.z_m = -rng.uniform(6.0, 25.0);
      pose.yaw_deg = rng.uniform(0.0, 360.0);
      const Mesh& obj = objects[static_cast<size_t>(rng.randint(static_cast<int64_t>(objects.size())))];
      pose.scale = 1.0;
      try {
        PhotoInsertionOptions o = insertion_options(a, est.volume_samples());
        o.seed = hash_counter(seed, i, static_cast<uint64_t>(attempt));
        const PhotoInsertion ins = insert_into_photo(light, photo.ldr, photo.depth, photo.camera, obj, pose, o);
        if (!ins.visible) continue;
        photo.ldr = ins.composite_ldr;  // later objects go into the augmented photo
        labels.push_back(kitti_label_line("Car", 0.0, 0, ins.box2d, ins.box3d));
        ++placed;
      } catch (const Error&) {
        continue;  // not on the ground / outside the view: draw another spot
      }
    }
    char id[16];
    std::snprintf(id, sizeof id, "%06zu", i);
    ImageWriteOptions lin;
    lin.transfer = Transfer::Linear;
    write_image(out.path(std::string("image_2/") + id + ".png"), photo.ldr, lin);
    std::string lab;
    for (const auto& l : labels) lab += l + "\n";
    write_text(out.path(std::string("label_2/") + id + ".txt"), lab);
    const Intrinsics& k = photo.camera.intrinsics();
    char calib[256];
    std::snprintf(calib, sizeof calib, "P2: %.6f 0 %.6f 0 0 %.6f %.6f 0 0 0 1 0\n", k.fx, k.cx, k.fy, k.cy);
    write_text(out.path(std::string("calib/") + id + ".txt"), calib);
    manifest.push_back({{"id", id}, {"source", sources[i].image}, {"objects", placed}, {"depth", photo.depth_source}});
    progress.update(static_cast<int64_t>(i + 1));
  }
  progress.finish();
  write_text(out.path("result.json"), json{{"images", manifest}}.dump(2) + "\n");
  out.commit();
  if (a.has("--json")) std::cout << json{{"images", manifest}}.dump() << "\n";
  std::fprintf(stderr, "wrote %zu images to %s\n", sources.size(), a.get("--out").c_str());
  return 0;
}

int run(int argc, char** argv) {
  cli::Args a("streetlight-insert",
              "streetlight-insert --image PHOTO --intrinsics FILE --object MODEL.glb --at X,Z [--yaw DEG] [--scale S]\n"
              "                   [--checkpoint CKPT] --out DIR [--depth FILE | --lidar BIN --calib FILE]\n"
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
               {"--object", "MODEL", "glTF/GLB model, or procedural:car (batch: repeatable)", true},
               {"--at", "X,Z", "ground position in metres (right, forward) of the first camera"},
               {"--yaw", "DEG", "object heading about +Y; 90 points its length away from the camera (default 90)"},
               {"--scale", "S", "uniform object scale (default 1)"},
               {"--checkpoint", "CKPT", "lighting or adversarial stage checkpoint (default: the released model, models/streetlight.safetensors)"},
               {"--out", "DIR", "output folder (written atomically)"},
               {"--exr", "", "also write the composite as linear EXR"},
               {"--sun-azimuth", "DEG", "edit the sun: world azimuth (Sec 3.2 sky vector)"},
               {"--sun-elevation", "DEG", "edit the sun: elevation above the horizon"},
               {"--sun-intensity", "X", "edit the sun: multiply its intensity by X"},
               {"--aa", "N", "primary rays per pixel (default 4)"},
               {"--light-samples", "N", "light samples per shading point, Eq. 2 (default 64)"},
               {"--shadow-rays", "N", "shadow rays per shadow-map pixel, Eq. 4 (default 128)"},
               {"--shadow-width", "N", "shadow-map width (default 160)"},
               {"--shadow-height", "N", "shadow-map height (default 90)"},
               {"--seed", "N", "sampling seed (default 0)"},
               {"--batch", "LIST", "batch mode: JSON list of {image, intrinsics, depth|lidar+calib} or KITTI folder"},
               {"--objects-per-image", "N", "batch: objects per image (default 1)"},
               {"--json", "", "print result.json on stdout"}});
  if (!a.parse(argc, argv)) return 0;
  return a.has("--batch") ? batch(a) : single(a);
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
