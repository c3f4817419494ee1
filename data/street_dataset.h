// Readers of the generated street dataset (format: docs/DATASET.md; writer:
// data/street_generator.h) for training.
//
// StreetDataset lists one split of index.json; load(i) reads sample ids()[i] completely:
// HDR as linear float, LDR PNGs as their stored values in [0, 1] (they are already the paper's
// gamma-encoded LDR, so no sRGB decoding), depth in metres (camera z, 0 where the view sees
// sky), masks as 0/1 floats. All tensors are F32 [C, H, W] ([H, W] for depth).
// SampleLoader walks a dataset in epochs, each a seeded shuffle (a pure function of
// (seed, epoch)), loading up to `prefetch` samples ahead on one background thread. A load
// error is rethrown by the next() that would have returned that sample. The destructor stops
// and joins the thread, even while it waits on a full queue.
// Throws: sl::Error naming the folder and split (bad index.json, unknown split), or the sample
// folder and file (missing or corrupt file, bad meta.json key).
#pragma once
#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <filesystem>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "autodiff/tensor.h"
#include "render/camera.h"

namespace sl::data {

struct StreetView {
  Tensor ldr;       // [3, H, W] in [0, 1], the stored LDR values (NOT sRGB-decoded)
  Tensor hdr;       // [3, H, W] linear HDR, or undefined when the file is absent
  Tensor depth;     // [H, W] metres, camera z; 0 where there is no surface (sky)
  Tensor sky_mask;  // [1, H, W] 0/1
  render::Camera camera;
};

struct StreetSample {
  std::string id;
  Tensor sky_hdr;                            // [3, Hs, Ws] true sky (linear HDR, full sphere)
  Tensor pano_hdr, pano_ldr, pano_sky_mask;  // [3, Hp, Wp], [3, Hp, Wp], [1, Hp, Wp]
  glm::dvec3 pano_position{0.0};
  glm::dvec3 sun_direction{0.0, 1.0, 0.0};
  // False where the sun direction is not a usable label (a real panorama whose sun is soft or
  // below the horizon, data/panorama_sample.h): the direction loss and sun metrics skip it.
  bool sun_known = true;
  // The weight of that label in the direction losses: 1, or data.ldr_low_label_weight for an LDR
  // panorama whose label is of low confidence (a hazy glare, a sun placed by hand).
  double sun_weight = 1.0;
  // A tone curve on the network's INPUT only (the view's LDR raised to this power before it is
  // resized into the image and unprojected; the rays' targets keep the view's LDR): the
  // tone-curve jitter of real crops (data/panorama_sample.h tone_stops), so photos from
  // cameras with other curves look like one domain. 1: none.
  double input_tone_gamma = 1.0;
  // False where sky_hdr is not linear radiance but a stand-in: an LDR panorama's codes^2.2, clipped
  // at the sun (data/ldr_panorama_sample.h). Its sun's energy is then no label.
  bool hdr_sky = true;
  double exposure = 1.0;
  std::vector<StreetView> views;
  bool has_insertion = false;
  // [3,H,W], [3,H,W], [1,H,W]; the mask is the object's sub-pixel coverage in [0, 1] (8-bit steps)
  Tensor insert_with_object_hdr, insert_without_object_hdr, insert_object_mask;
  // Optional (datagen insertion.light_probe): [3, Hp, Wp] HDR panorama from the object's centre,
  // in the scene without the object: the light the object receives. Undefined when absent.
  Tensor insert_light_probe_hdr;
  glm::dvec3 light_probe_position{0.0};
  std::string object_glb;  // absolute path of the object's .glb (object frame)
  double object_x = 0.0, object_z = 0.0, object_yaw_deg = 0.0, object_scale = 1.0;
  std::array<double, 4> box2d{};  // x1 y1 x2 y2 (pixels of view 0)
  std::array<double, 7> box3d{};  // h w l x y z ry (KITTI, view 0's camera frame)
};

// A dataset file (index.json, meta.json) parsed; sl::Error "<what>: ..." naming the path when it
// cannot be opened or is not JSON.
nlohmann::json read_json(const std::filesystem::path& path, const std::string& what);

// What a sample says of its sun, read from meta.json alone (no image is decoded): the label,
// whether it is usable, and view 0's camera (the input view of training and evaluation).
struct SunLabel {
  glm::dvec3 sun_direction{0.0, 1.0, 0.0};
  bool sun_known = true;
  render::Camera camera;
};

class StreetDataset {
 public:
  StreetDataset(const std::string& dir, const std::string& split);  // throws naming dir/split
  size_t size() const { return ids_.size(); }
  const std::vector<std::string>& ids() const { return ids_; }
  const std::string& dir() const { return dir_; }
  StreetSample load(size_t index) const;  // throws naming the sample folder and file
  SunLabel load_sun_label(size_t index) const;  // meta.json only; throws like load()

 private:
  std::string dir_, split_;
  std::vector<std::string> ids_;
};

// The order of epoch `epoch`: a permutation of [0, n) that depends only on (seed, epoch).
std::vector<size_t> epoch_order(size_t n, uint64_t seed, uint64_t epoch);

// Shuffled (by seed and epoch, deterministic), prefetching on a background thread.
class SampleLoader {
 public:
  SampleLoader(const StreetDataset& dataset, uint64_t seed, size_t prefetch = 2);
  ~SampleLoader();
  SampleLoader(const SampleLoader&) = delete;
  SampleLoader& operator=(const SampleLoader&) = delete;

  StreetSample next();     // the next sample; a new epoch starts after the last one
  uint64_t epoch() const;  // 0-based epoch of the sample next() returned last (0 before the first)

 private:
  struct Item {
    StreetSample sample;
    uint64_t epoch = 0;
    std::exception_ptr error;
  };
  void run();

  const StreetDataset& dataset_;
  uint64_t seed_;
  size_t prefetch_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Item> queue_;
  bool stop_ = false;
  uint64_t epoch_ = 0;
  std::thread thread_;
};

}  // namespace sl::data
