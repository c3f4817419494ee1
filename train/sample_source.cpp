// Sample sources for the lighting stages. See sample_source.h.
#include "train/sample_source.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string_view>
#include <unordered_map>

#include "data/hdri_folder.h"
#include "data/hdri_split.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/places.h"
#include "data/sun_labels.h"
#include "util/error.h"
#include "util/file_kind.h"
#include "util/random.h"

using sl::data::HdriFolder;
using sl::data::panorama_street_sample;
using sl::data::PanoramaSampleOptions;
using sl::data::read_hdri_split;
using sl::data::sanitized_panorama;
using sl::data::StreetDataset;
using sl::data::StreetSample;

namespace sl::train {

namespace {
constexpr std::string_view kHdrCropPrefix = "hdri:";
constexpr std::string_view kLdrCropPrefix = "ldr:";
}  // namespace

SampleOrigin sample_origin(const std::string& id) {
  if (id.starts_with(kHdrCropPrefix)) return SampleOrigin::HdrCrop;
  if (id.starts_with(kLdrCropPrefix)) return SampleOrigin::LdrCrop;
  return SampleOrigin::Street;
}

std::string crop_sample_id(SampleOrigin origin, const std::string& file, uint64_t stream) {
  SL_CHECK(origin != SampleOrigin::Street, "crop_sample_id: a generated street keeps its own id");
  return std::string(origin == SampleOrigin::HdrCrop ? kHdrCropPrefix : kLdrCropPrefix) + file + "#" +
         std::to_string(stream);
}

size_t sample_bytes(const StreetSample& sample) {
  size_t bytes = 0;
  const auto add = [&](const Tensor& t) {
    if (t.defined()) bytes += static_cast<size_t>(t.numel()) * dtype_size(t.dtype());
  };
  for (const Tensor* t : {&sample.sky_hdr, &sample.pano_hdr, &sample.pano_ldr, &sample.pano_sky_mask,
                          &sample.insert_with_object_hdr, &sample.insert_without_object_hdr, &sample.insert_object_mask,
                          &sample.insert_light_probe_hdr})
    add(*t);
  for (const auto& v : sample.views)
    for (const Tensor* t : {&v.ldr, &v.hdr, &v.depth, &v.sky_mask}) add(*t);
  return bytes;
}

namespace {

// The decoded samples of dataset_source. Tensors share their storage when a StreetSample is
// copied, so a hit costs no copy; nothing downstream writes into a loaded sample's tensors (the
// flip and the batch build new ones), which the bit-identity test of tests/train checks.
struct SampleCache {
  std::mutex mutex;
  std::unordered_map<size_t, StreetSample> samples;
  size_t bytes = 0;
  size_t capacity = 0;
};

// Item i of a real-panorama source of n panoramas: training (vary_with_draw) cycles through them
// with the draw as the augmentation stream; fixed sets give each panorama `per` consecutive items
// with the item's index as the stream.
struct PanoramaDraw {
  size_t panorama;
  uint64_t stream;
};
// The random stream of a place-balanced draw's panorama (apart from the crop's own streams).
constexpr uint64_t kPlaceStream = 0x706c616365ULL;  // "place"

PanoramaDraw panorama_draw(size_t i, uint64_t draw, bool vary_with_draw, size_t n, size_t per) {
  if (vary_with_draw) return {i % n, draw};
  return {std::min(i / per, n - 1), static_cast<uint64_t>(i)};
}

}  // namespace

SampleSource dataset_source(const std::string& dir, const std::string& split, size_t max_items, size_t cache_bytes) {
  auto ds = std::make_shared<StreetDataset>(dir, split);
  const size_t n = max_items > 0 ? std::min(max_items, ds->size()) : ds->size();
  if (cache_bytes == 0) return SampleSource{n, [ds](size_t i, uint64_t) { return ds->load(i); }};
  auto cache = std::make_shared<SampleCache>();
  cache->capacity = cache_bytes;
  return SampleSource{n, [ds, cache](size_t i, uint64_t) {
                        {
                          std::lock_guard<std::mutex> lock(cache->mutex);
                          const auto it = cache->samples.find(i);
                          if (it != cache->samples.end()) return it->second;
                        }
                        StreetSample s = ds->load(i);  // decoded outside the lock
                        const size_t b = sample_bytes(s);
                        std::lock_guard<std::mutex> lock(cache->mutex);
                        if (cache->bytes + b <= cache->capacity && cache->samples.emplace(i, s).second) cache->bytes += b;
                        return s;
                      }};
}

SampleSource panorama_source(const std::vector<std::string>& paths, const PanoramaSampleOptions& options, uint64_t seed,
                             size_t items, bool vary_with_draw) {
  SL_CHECK(!paths.empty(), "panorama_source: no panoramas");
  const HdriFolder folder(paths);
  auto panos = std::make_shared<std::vector<Tensor>>();
  auto names = std::make_shared<std::vector<std::string>>();
  for (size_t i = 0; i < folder.size(); ++i) {
    const std::string name = std::filesystem::path(folder.path(i)).filename().string();
    panos->push_back(sanitized_panorama(folder.load(i), folder.path(i)));
    names->push_back(name);
  }
  const size_t n = panos->size();
  const size_t per = std::max<size_t>(1, items / n);
  return SampleSource{items, [panos, names, options, seed, vary_with_draw, n, per](size_t i, uint64_t draw) {
                        const auto [k, stream] = panorama_draw(i, draw, vary_with_draw, n, per);
                        return panorama_street_sample((*panos)[k], crop_sample_id(SampleOrigin::HdrCrop, (*names)[k], stream),
                                                      seed, stream, options);
                      }};
}

SampleSource ldr_panorama_source(const std::vector<std::string>& paths, const std::string& labels_path,
                                 const PanoramaSampleOptions& options, uint64_t seed, size_t items, bool vary_with_draw,
                                 int working_width, const LdrPlaceBalance& balance) {
  SL_CHECK(!paths.empty(), "ldr_panorama_source: no panoramas");
  SL_CHECK(working_width >= 2 && working_width % 2 == 0, "ldr_panorama_source: working width must be even, got ",
           working_width);
  const data::SunLabels labels = data::read_sun_labels(labels_path);
  SL_CHECK(balance.exponent == 1.0 || balance.places.size() == paths.size(), "ldr_panorama_source: ",
           balance.places.size(), " places for ", paths.size(), " panoramas");
  std::vector<size_t> order(paths.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return paths[a] < paths[b]; });
  std::vector<std::string> sorted, sorted_places;
  for (size_t i : order) {
    sorted.push_back(paths[i]);
    if (balance.exponent != 1.0) sorted_places.push_back(balance.places[i]);
  }
  auto panos = std::make_shared<std::vector<data::LdrPanorama>>();
  auto names = std::make_shared<std::vector<std::string>>();
  for (const std::string& path : sorted) {
    const std::string name = std::filesystem::path(path).filename().string();
    const data::PanoramaSunLabel* label = labels.find(name);
    SL_CHECK(label != nullptr, "LDR panorama '", path, "' has no row in the sun labels '", labels_path, "'");
    data::ImageReadOptions ro;
    ro.transfer = data::Transfer::Linear;  // codes / 255 (data/ldr_panorama_sample.h)
    ro.channels = 3;
    const Tensor full = data::read_image(path, ro);
    SL_CHECK(full.size(2) == 2 * full.size(1), "LDR panorama '", path, "' is ", full.size(2), "x", full.size(1),
             "; an equirectangular panorama is 2:1 (width = 2 x height)");
    data::LdrPanorama p;
    p.ldr = data::resize_area(full, working_width / 2, working_width).contiguous();
    p.linear = data::ldr_linear(p.ldr);
    p.sky_mask = data::estimate_sky_mask(p.linear);  // ldr_sky_mask's rule, on the linear radiance kept
    p.sun_known = label->has_position;
    p.sun_weight = label->confidence == data::LabelConfidence::Low ? options.low_label_weight : 1.0;
    if (p.sun_known) p.sun_direction = labels.direction(*label, static_cast<int>(full.size(2)), static_cast<int>(full.size(1)));
    panos->push_back(std::move(p));
    names->push_back(name);
  }
  const size_t n = panos->size();
  const size_t per = std::max<size_t>(1, items / n);
  // Place balance: the cumulative weights of the panoramas (sorted order), empty when off.
  std::vector<double> cumulative;
  if (balance.exponent != 1.0 && vary_with_draw) {
    cumulative = data::place_balanced_weights(sorted_places, balance.exponent);
    for (size_t k = 1; k < cumulative.size(); ++k) cumulative[k] += cumulative[k - 1];
  }
  return SampleSource{items, [panos, names, options, seed, vary_with_draw, n, per, cumulative](size_t i, uint64_t draw) {
                        auto [k, stream] = panorama_draw(i, draw, vary_with_draw, n, per);
                        if (!cumulative.empty()) k = data::pick_weighted(cumulative, uniform01(seed, kPlaceStream, draw));
                        return data::ldr_panorama_street_sample((*panos)[k], crop_sample_id(SampleOrigin::LdrCrop, (*names)[k], stream),
                                                                seed, stream, options);
                      }};
}

SampleSource mixed_source(SampleSource a, SampleSource b, double fraction_b) {
  SL_CHECK(fraction_b >= 0 && fraction_b < 1, "mixed_source: fraction must lie in [0, 1), got ", fraction_b);
  if (fraction_b == 0 || b.size == 0) return a;
  const size_t extra =
      std::max<size_t>(1, static_cast<size_t>(std::llround(static_cast<double>(a.size) * fraction_b / (1 - fraction_b))));
  const size_t na = a.size, nb = b.size;
  return SampleSource{na + extra, [a = std::move(a), b = std::move(b), na, nb](size_t i, uint64_t draw) {
                        return i < na ? a.load(i, draw) : b.load((i - na) % nb, draw);
                      }};
}

std::vector<std::string> configured_hdri_paths(const nlohmann::json& config, const std::string& split_key) {
  const auto& d = config.at("data");
  const std::string dir = d.value("hdri_dir", std::string()), split_file = d.value("hdri_split", std::string());
  if (dir.empty()) return {};
  if (split_file.empty()) return split_key == "hdri_train_split" ? HdriFolder(dir).paths() : std::vector<std::string>{};
  return read_hdri_split(split_file).split_paths(dir, d.at(split_key).get<std::string>());
}

std::vector<std::string> configured_ldr_paths(const nlohmann::json& config, const std::string& split_key) {
  const auto& d = config.at("data");
  const std::string dir = d.value("ldr_dir", std::string()), split_file = d.value("ldr_split", std::string());
  if (dir.empty()) return {};
  if (split_file.empty()) {
    if (split_key != "hdri_train_split") return {};
    return files_with_extension(dir, {".jpg", ".jpeg", ".png"});
  }
  return read_hdri_split(split_file).split_paths(dir, d.at(split_key).get<std::string>());
}

std::string configured_ldr_labels(const nlohmann::json& config) {
  const auto& d = config.at("data");
  const std::string labels = d.value("ldr_labels", std::string());
  if (!labels.empty()) return labels;
  return (std::filesystem::path(d.value("ldr_dir", std::string())) / "sun_labels.csv").string();
}

LdrPlaceBalance configured_ldr_place_balance(const nlohmann::json& config, const std::vector<std::string>& paths) {
  const auto& d = config.at("data");
  LdrPlaceBalance b;
  b.exponent = d.value("ldr_place_balance", 1.0);
  if (b.exponent == 1.0) return b;
  std::string table = d.value("ldr_places", std::string());
  data::Places places;
  if (!table.empty()) {
    places = data::read_places(table);
  } else {
    table = (std::filesystem::path(d.value("ldr_dir", std::string())) / "places.csv").string();
    if (std::filesystem::exists(table)) places = data::read_places(table);
  }
  for (const auto& p : paths) b.places.push_back(places.place_of(std::filesystem::path(p).filename().string()));
  return b;
}

SampleSource concat_sources(SampleSource a, SampleSource b) {
  const size_t na = a.size;
  return SampleSource{na + b.size, [a = std::move(a), b = std::move(b), na](size_t i, uint64_t draw) {
                        return i < na ? a.load(i, draw) : b.load(i - na, draw);
                      }};
}

}  // namespace sl::train
