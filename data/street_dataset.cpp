#include "data/street_dataset.h"

#include <filesystem>
#include <fstream>
#include <utility>

#include <nlohmann/json.hpp>

#include "autodiff/shape_ops.h"
#include "data/image_io.h"
#include "util/error.h"
#include "util/random.h"

using sl::render::Camera;
using sl::render::Intrinsics;

namespace sl::data {

namespace fs = std::filesystem;
using json = nlohmann::json;

json read_json(const fs::path& path, const std::string& what) {
  std::ifstream f(path);
  SL_CHECK(f.good(), what, ": cannot open '", path.string(), "'");
  try {
    return json::parse(f);
  } catch (const std::exception& e) {
    fail(what, ": '", path.string(), "' is not valid JSON: ", e.what());
  }
}

namespace {

// Looks up a nested key, naming the file and the key path when it is missing.
const json& key(const json& j, const std::string& k, const fs::path& file) {
  SL_CHECK(j.is_object() && j.contains(k), "StreetDataset: '", file.string(), "' lacks key '", k, "'");
  return j.at(k);
}

double number(const json& j, const std::string& k, const fs::path& file) {
  const json& v = key(j, k, file);
  SL_CHECK(v.is_number(), "StreetDataset: '", file.string(), "': key '", k, "' must be a number, got ", v.dump());
  return v.get<double>();
}

glm::dvec3 vec3(const json& j, const std::string& k, const fs::path& file) {
  const json& v = key(j, k, file);
  SL_CHECK(v.is_array() && v.size() == 3 && v[0].is_number() && v[1].is_number() && v[2].is_number(),
           "StreetDataset: '", file.string(), "': key '", k, "' must be 3 numbers, got ", v.dump());
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}

template <size_t N>
std::array<double, N> numbers(const json& j, const std::string& k, const fs::path& file) {
  const json& v = key(j, k, file);
  SL_CHECK(v.is_array() && v.size() == N, "StreetDataset: '", file.string(), "': key '", k, "' must hold ", N,
           " numbers, got ", v.dump());
  std::array<double, N> out{};
  for (size_t i = 0; i < N; ++i) {
    SL_CHECK(v[i].is_number(), "StreetDataset: '", file.string(), "': key '", k, "' must hold numbers");
    out[i] = v[i].get<double>();
  }
  return out;
}

// Every reader error names the sample folder and the file (image_io errors name the file).
template <class F>
auto in_sample(const fs::path& dir, const std::string& file, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const std::exception& e) {
    fail("StreetDataset: sample '", dir.string(), "', file '", file, "': ", e.what());
  }
}

Tensor read_float(const fs::path& dir, const std::string& file, int channels) {
  return in_sample(dir, file, [&] {
    ImageReadOptions o;
    o.channels = channels;
    o.transfer = Transfer::Linear;
    return read_image((dir / file).string(), o).contiguous();
  });
}

Tensor read_stored(const fs::path& dir, const std::string& file, int channels) {
  return read_float(dir, file, channels);  // Linear transfer keeps PNG codes as stored values / 255
}

Tensor read_mask(const fs::path& dir, const std::string& file) {
  Tensor m = read_stored(dir, file, 1);
  float* p = m.data<float>();
  for (int64_t i = 0; i < m.numel(); ++i) p[i] = p[i] >= 0.5f ? 1.0f : 0.0f;
  return m;
}

int image_size(const json& k, const std::string& name, const fs::path& meta) {
  const double v = number(k, name, meta);
  SL_CHECK(v >= 1 && v <= 65536 && v == static_cast<double>(static_cast<int>(v)), "StreetDataset: '",
           meta.string(), "': intrinsics key '", name, "' must be an integer in [1, 65536], got ", v);
  return static_cast<int>(v);
}

Camera read_camera(const json& v, const fs::path& meta) {
  const json& k = key(v, "intrinsics", meta);
  Intrinsics in;
  in.fx = number(k, "fx", meta);
  in.fy = number(k, "fy", meta);
  in.cx = number(k, "cx", meta);
  in.cy = number(k, "cy", meta);
  in.width = image_size(k, "width", meta);
  in.height = image_size(k, "height", meta);
  const auto r = numbers<9>(v, "rotation_cam_to_world", meta);
  glm::dmat3 rot;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rot[j][i] = r[static_cast<size_t>(3 * i + j)];  // row-major → glm columns
  return in_sample(meta.parent_path(), meta.filename().string(),
                   [&] { return Camera(in, rot, vec3(v, "position", meta)); });
}

// Sample ids and the file names of meta.json name entries of ONE folder: a path separator,
// "." or ".." would let a hostile index or meta.json make the reader open any file.
bool plain_name(const std::string& name) {
  return !name.empty() && name != "." && name != ".." && name.find('/') == std::string::npos &&
         name.find('\0') == std::string::npos;
}

std::string file_name(const json& files, const std::string& k, const fs::path& meta) {
  const json& v = key(files, k, meta);
  SL_CHECK(v.is_string(), "StreetDataset: '", meta.string(), "': files key '", k, "' must be a string");
  SL_CHECK(plain_name(v.get<std::string>()), "StreetDataset: '", meta.string(), "': files key '", k,
           "' must be a file name in the sample folder, got '", v.get<std::string>(), "'");
  return v.get<std::string>();
}

}  // namespace

StreetDataset::StreetDataset(const std::string& dir, const std::string& split) : dir_(dir), split_(split) {
  const fs::path index = fs::path(dir) / "index.json";
  const std::string what = "StreetDataset('" + dir + "', '" + split + "')";
  SL_CHECK(fs::is_regular_file(index), what, ": no index.json in '", dir, "'");
  const json j = read_json(index, what);
  SL_CHECK(j.is_object() && j.contains("format") && j["format"] == "streetlight-dataset", what, ": '",
           index.string(), "' is not a streetlight-dataset index (key 'format')");
  SL_CHECK(j.contains("version") && j["version"] == 1, what, ": '", index.string(), "' has unsupported version ",
           j.contains("version") ? j["version"].dump() : std::string("(none)"));
  SL_CHECK(j.contains("splits") && j["splits"].is_object(), what, ": '", index.string(), "' lacks 'splits'");
  SL_CHECK(j["splits"].contains(split), what, ": unknown split '", split, "' in '", index.string(),
           "' (splits: train, val, test)");
  for (const json& id : j["splits"][split]) {
    SL_CHECK(id.is_string(), what, ": '", index.string(), "': split '", split, "' holds a non-string id");
    SL_CHECK(plain_name(id.get<std::string>()), what, ": '", index.string(), "': split '", split,
             "' holds the id '", id.get<std::string>(), "', which is not a folder name");
    ids_.push_back(id.get<std::string>());
  }
}

namespace {

// A sample's folder and its parsed meta.json.
std::pair<fs::path, json> sample_meta(const std::string& dir, const std::string& split,
                                      const std::vector<std::string>& ids, size_t index) {
  SL_CHECK(index < ids.size(), "StreetDataset('", dir, "', '", split, "'): index ", index, " out of range for ",
           ids.size(), " samples");
  const fs::path d = fs::path(dir) / "samples" / ids[index];
  SL_CHECK(fs::is_directory(d), "StreetDataset: sample folder '", d.string(), "' is missing");
  const fs::path meta_path = d / "meta.json";
  SL_CHECK(fs::is_regular_file(meta_path), "StreetDataset: sample '", d.string(), "', file 'meta.json' is missing");
  return {d, read_json(meta_path, "StreetDataset")};
}

// Streets lit by a real HDRI whose sun is soft carry no usable direction label.
bool sun_hard(const json& meta) {
  if (meta.contains("lighting") && meta["lighting"].is_object() && meta["lighting"].contains("sun_hard") &&
      meta["lighting"]["sun_hard"].is_boolean())
    return meta["lighting"]["sun_hard"].get<bool>();
  return true;
}

}  // namespace

SunLabel StreetDataset::load_sun_label(size_t index) const {
  const auto [d, meta] = sample_meta(dir_, split_, ids_, index);
  const fs::path meta_path = d / "meta.json";
  SunLabel l;
  l.sun_direction = vec3(meta, "sun_direction", meta_path);
  l.sun_known = sun_hard(meta);
  const json& views = key(meta, "views", meta_path);
  SL_CHECK(views.is_array() && !views.empty(), "StreetDataset: '", meta_path.string(), "': 'views' must be a non-empty list");
  l.camera = read_camera(views[0], meta_path);
  return l;
}

StreetSample StreetDataset::load(size_t index) const {
  StreetSample s;
  const auto [d, meta] = sample_meta(dir_, split_, ids_, index);
  s.id = ids_[index];
  const fs::path meta_path = d / "meta.json";

  s.sun_direction = vec3(meta, "sun_direction", meta_path);
  s.sun_known = sun_hard(meta);
  s.exposure = number(meta, "exposure", meta_path);
  const json& pano = key(meta, "panorama", meta_path);
  s.pano_position = vec3(pano, "position", meta_path);
  const json& pf = key(pano, "files", meta_path);
  s.pano_hdr = read_float(d, file_name(pf, "hdr", meta_path), 3);
  s.pano_ldr = read_stored(d, file_name(pf, "ldr", meta_path), 3);
  s.pano_sky_mask = read_mask(d, file_name(pf, "sky_mask", meta_path));
  s.sky_hdr = read_float(d, file_name(key(meta, "sky", meta_path), "file", meta_path), 3);

  for (const json& v : key(meta, "views", meta_path)) {
    StreetView view;
    view.camera = read_camera(v, meta_path);
    const Intrinsics& k = view.camera.intrinsics();
    const json& f = key(v, "files", meta_path);
    view.ldr = read_stored(d, file_name(f, "ldr", meta_path), 3);
    if (f.is_object() && f.contains("hdr") && fs::exists(d / file_name(f, "hdr", meta_path)))
      view.hdr = read_float(d, file_name(f, "hdr", meta_path), 3);
    const std::string depth = file_name(f, "depth", meta_path);
    // A named copy: C++20 lambdas may not capture a structured binding (clang 14 refuses it).
    const fs::path depth_path = d / depth;
    view.depth = reshape(in_sample(d, depth,
                                   [&] { return read_depth(depth_path.string(), MissingDepth::Zero, k.width, k.height); })
                             .contiguous(),
                         {k.height, k.width});
    view.sky_mask = read_mask(d, file_name(f, "sky_mask", meta_path));
    SL_CHECK(view.ldr.size(1) == k.height && view.ldr.size(2) == k.width, "StreetDataset: sample '", d.string(),
             "': view LDR size differs from its intrinsics");
    s.views.push_back(std::move(view));
  }

  const json& obj = key(meta, "object", meta_path);
  s.has_insertion = !obj.is_null();
  if (s.has_insertion) {
    const json& f = key(obj, "files", meta_path);
    s.insert_with_object_hdr = read_float(d, file_name(f, "with_object_hdr", meta_path), 3);
    s.insert_without_object_hdr = read_float(d, file_name(f, "without_object_hdr", meta_path), 3);
    s.insert_object_mask = read_stored(d, file_name(f, "object_mask", meta_path), 1);
    if (f.contains("light_probe_hdr")) {
      s.insert_light_probe_hdr = read_float(d, file_name(f, "light_probe_hdr", meta_path), 3);
      s.light_probe_position = vec3(obj, "light_probe_position", meta_path);
    }
    s.object_glb = (d / file_name(obj, "file", meta_path)).string();
    SL_CHECK(fs::is_regular_file(s.object_glb), "StreetDataset: sample '", d.string(), "', file '",
             file_name(obj, "file", meta_path), "' is missing");
    const json& p = key(obj, "placement", meta_path);
    s.object_x = number(p, "x_m", meta_path);
    s.object_z = number(p, "z_m", meta_path);
    s.object_yaw_deg = number(p, "yaw_deg", meta_path);
    s.object_scale = number(p, "scale", meta_path);
    s.box2d = numbers<4>(obj, "box2d", meta_path);
    s.box3d = numbers<7>(obj, "box3d", meta_path);
  }
  return s;
}

std::vector<size_t> epoch_order(size_t n, uint64_t seed, uint64_t epoch) {
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  Rng rng(seed, 0xE90C0000ULL + epoch);
  for (size_t i = n; i > 1; --i) std::swap(order[i - 1], order[static_cast<size_t>(rng.randint(static_cast<int64_t>(i)))]);
  return order;
}

SampleLoader::SampleLoader(const StreetDataset& dataset, uint64_t seed, size_t prefetch)
    : dataset_(dataset), seed_(seed), prefetch_(std::max<size_t>(1, prefetch)) {
  SL_CHECK(dataset.size() > 0, "SampleLoader: the dataset '", dataset.dir(), "' split is empty");
  thread_ = std::thread([this] { run(); });
}

SampleLoader::~SampleLoader() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void SampleLoader::run() {
  for (uint64_t epoch = 1;; ++epoch) {
    for (size_t index : epoch_order(dataset_.size(), seed_, epoch - 1)) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [&] { return stop_ || queue_.size() < prefetch_; });
        if (stop_) return;
      }
      Item item;
      item.epoch = epoch;
      try {
        item.sample = dataset_.load(index);
      } catch (...) {
        item.error = std::current_exception();
      }
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (stop_) return;
        queue_.push_back(std::move(item));
      }
      cv_.notify_all();
    }
  }
}

StreetSample SampleLoader::next() {
  std::unique_lock<std::mutex> lock(mutex_);
  cv_.wait(lock, [&] { return !queue_.empty(); });
  Item item = std::move(queue_.front());
  queue_.pop_front();
  epoch_ = item.epoch - 1;
  lock.unlock();
  cv_.notify_all();
  if (item.error) std::rethrow_exception(item.error);
  return std::move(item.sample);
}

uint64_t SampleLoader::epoch() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return epoch_;
}

}  // namespace sl::data
