#include "tools/common/insert_batch.h"

#include <algorithm>
#include <cctype>
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

using sl::data::cover_label;
using sl::data::footprints_within;
using sl::data::format_kitti_label;
using sl::data::ImageWriteOptions;
using sl::data::kitti_box3d;
using sl::data::kitti_calibration_from_intrinsics;
using sl::data::kitti_calibration_text;
using sl::data::KittiLabel;
using sl::data::occlusion_level;
using sl::data::read_kitti_labels;
using sl::train::estimate_with_shadow_sun;
using sl::train::ShadowSunLighting;
using sl::data::Transfer;
using sl::data::write_image;
using sl::render::Intrinsics;
using sl::render::Mesh;
using sl::render::Placement;

namespace fs = std::filesystem;
using nlohmann::json;
using namespace sl::train;

namespace sl::cli {

namespace {

struct BatchItem {
  std::string id, labels, calib;
  PhotoSources sources;
};

std::vector<BatchItem> batch_items(const std::string& spec, const cli::Args& a) {
  std::vector<BatchItem> out;
  auto base = [&](PhotoSources s) {
    s.camera_height_m = a.number("--camera-height", 1.65);
    s.pitch_deg = a.number("--pitch", 0.0);
    if (s.fov_deg == 0.0 && a.has("--fov")) s.fov_deg = a.number("--fov", 0.0);  // the list's own "fov" wins
    return s;
  };
  const auto is_photo = [](const fs::path& p) {
    std::string ext = p.extension().string();
    for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
  };
  if (fs::is_directory(spec) && !fs::is_directory(fs::path(spec) / "image_2")) {
    // A plain folder of photos (a phone's, a camera's): every PNG or JPEG in it, its intrinsics
    // from --fov or its EXIF focal length (train/photo_input.h), the ground plane for depth.
    std::vector<fs::path> images;
    for (const auto& e : fs::directory_iterator(spec))
      if (e.is_regular_file() && is_photo(e.path())) images.push_back(e.path());
    std::sort(images.begin(), images.end());
    SL_CHECK(!images.empty(), "batch folder '", spec,
             "' has neither an image_2/ subfolder (KITTI layout) nor PNG or JPEG photos");
    for (const auto& img : images) {
      BatchItem it;
      it.id = img.stem().string();
      PhotoSources s;
      s.image = img.string();
      it.sources = base(s);
      out.push_back(it);
    }
  } else if (fs::is_directory(spec)) {
    const fs::path dir(spec);
    std::vector<fs::path> images;
    for (const auto& e : fs::directory_iterator(dir / "image_2"))
      if (is_photo(e.path())) images.push_back(e.path());
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
                        const std::vector<std::string>& classes,
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
    const size_t which = static_cast<size_t>(rng.randint(static_cast<int64_t>(objects.size())));
    const Mesh& obj = objects[which];
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
    l.type = classes[which];
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

}  // namespace

int insert_batch(const cli::Args& a) {
  SL_CHECK(a.has("--out"), "--batch needs --out DIR");
  const std::vector<BatchItem> items = batch_items(a.get("--batch"), a);
  const std::vector<std::string> specs = a.has("--object") ? a.all("--object") : std::vector<std::string>{"procedural:car"};
  std::vector<Mesh> objects;
  for (const auto& s : specs) objects.push_back(load_object(s));
  const std::vector<std::string> classes = cli::object_classes(a, objects.size());
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
    const BatchResult r = augment_one(a, est, objects, classes, items[i], i, out, done);
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

}  // namespace sl::cli
