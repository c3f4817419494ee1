// Where the lighting stages (Sec 3.4) get their samples: generated street scenes
// (data/street_dataset.h), real HDR panoramas as augmented perspective crops
// (data/panorama_sample.h), real LDR street panoramas with hand-labelled suns as augmented
// crops (data/ldr_panorama_sample.h, the paper's HoliCity branch in kind), and mixtures.
//
// A SampleSource has `size` items; load(index, draw) returns item `index`. `draw` is the global
// counter of samples drawn so far in training (step·batch + i): a real-panorama source uses it
// as the augmentation stream, so the same panorama gives a new crop every time it is drawn,
// while a street dataset ignores it. Both arguments make the result a pure function, so a run
// resumed at any step reproduces the same samples. load() must be safe to call from a
// background thread while the stage computes (the loader prefetches the next batch).
//
// mixed_source(a, b, f): a's items, then enough virtual items cycling over b that a shuffled
// epoch draws from b with probability f (= b_items / (a.size + b_items), rounded).
// concat_sources(a, b): a's items, then b's.
// Throws: sl::Error naming the folder, split file or panorama (read errors surface at load()).
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/ldr_panorama_sample.h"
#include "data/panorama_sample.h"
#include "data/street_dataset.h"

namespace sl::train {

// Where a sample came from, told by its id: a crop of a real HDR panorama is "hdri:<file>#<stream>",
// a crop of a real LDR panorama "ldr:<file>#<stream>", and any other id is a generated street. The
// sources below write these ids (crop_sample_id); the stage reads them back (sample_origin) to
// group its validation errors and to label the domain classifier (train/lighting_stage.h).
enum class SampleOrigin { Street, HdrCrop, LdrCrop };
SampleOrigin sample_origin(const std::string& id);
// crop_sample_id(HdrCrop or LdrCrop, file, stream); throws for Street (a street keeps its own id).
std::string crop_sample_id(SampleOrigin origin, const std::string& file, uint64_t stream);

struct SampleSource {
  size_t size = 0;
  std::function<data::StreetSample(size_t index, uint64_t draw)> load;
};

// A generated street dataset's split (its first max_items items; 0: all). With cache_bytes > 0,
// each decoded sample is kept in memory after its first load while the kept samples fit in
// cache_bytes (none is evicted; later ones are decoded on every load). load() is a pure function
// of the index either way, so the cache changes speed, never results (data.cache_mb; a training
// epoch otherwise decodes every EXR and PNG of the split again).
SampleSource dataset_source(const std::string& dir, const std::string& split, size_t max_items = 0,
                            size_t cache_bytes = 0);

// Bytes of the decoded tensors of a sample (what the cache above charges for it).
size_t sample_bytes(const data::StreetSample& sample);

// Real panoramas (paths: e.g. HdriSplit::split_paths), read once. Training: item i is panorama
// i mod n with augmentation stream `draw`. Fixed (vary_with_draw = false, for validation and
// evaluation): item i is panorama i / crops_per_panorama with stream i, and no flip or jitter
// is added beyond what `options` says.
SampleSource panorama_source(const std::vector<std::string>& paths, const data::PanoramaSampleOptions& options,
                             uint64_t seed, size_t items, bool vary_with_draw);

// Real LDR panoramas (paths, e.g. from configs/pano_ldr_split.json) with their rows of the sun
// labels file `labels_path` (data/sun_labels.h; every panorama must have one), read once and
// area-resized to working_width × working_width/2 (the benchmark's working size,
// train/real_sky_benchmark.h), each with its sky mask (ldr_sky_mask). Items as panorama_source.
// Panoramas labelled none, or occluded without a position, are kept: their samples have
// sun_known = false and still teach the sky, the pseudo-labels and the radiance.
// Memory: every panorama is held decoded, 14·W² bytes at working width W (its codes and
// linear radiance as float, 3 channels each, and its mask): 14.7 MB at 1024, 3.7 MB at 512. The
// 522 training panoramas of configs/pano_ldr_split.json take 7.7 GB at 1024 and 1.9 GB at 512
// (data.ldr_working_width; the real-sky benchmark always reads at 1024). A sample's low-confidence
// label weighs options.low_label_weight (StreetSample::sun_weight).
//
// Place balance (data.ldr_place_balance, data/places.h): with balance.exponent < 1, a training
// draw (vary_with_draw) picks its panorama at random, a pure function of (seed, draw), with the
// weights place_balanced_weights gives the panoramas' places (balance.places, one per path in
// the order of `paths`), instead of cycling through them: a place of m panoramas gets a share
// proportional to m^exponent. Exponent 1 (the default) leaves the cycle as it was, bit for bit.
// Fixed sets ignore it.
struct LdrPlaceBalance {
  double exponent = 1.0;
  std::vector<std::string> places;  // one per path; needed when exponent < 1
};
SampleSource ldr_panorama_source(const std::vector<std::string>& paths, const std::string& labels_path,
                                 const data::PanoramaSampleOptions& options, uint64_t seed, size_t items,
                                 bool vary_with_draw, int working_width = 1024, const LdrPlaceBalance& balance = {});

// The places of `paths` (file names looked up in data.ldr_places, or places.csv beside the
// images when that key is empty; a missing default table leaves every file to its repository
// prefix, data/places.h), and the balance data.ldr_place_balance asks for.
LdrPlaceBalance configured_ldr_place_balance(const nlohmann::json& config, const std::vector<std::string>& paths);

SampleSource mixed_source(SampleSource a, SampleSource b, double fraction_b);

// The real panoramas a config names for one split: data.hdri_dir filtered by the split file
// data.hdri_split under the split named by data.<split_key> ("hdri_train_split" or
// "hdri_val_split"). Without a split file, every panorama of the folder is a training one and
// there is no validation one. Empty when data.hdri_dir is empty.
std::vector<std::string> configured_hdri_paths(const nlohmann::json& config, const std::string& split_key);
// The same for the LDR panoramas: data.ldr_dir filtered by data.ldr_split under the split named by
// data.<split_key> (the same keys as the HDR panoramas'); and their labels file, data.ldr_labels
// or, when empty, sun_labels.csv beside the images.
std::vector<std::string> configured_ldr_paths(const nlohmann::json& config, const std::string& split_key);
std::string configured_ldr_labels(const nlohmann::json& config);
SampleSource concat_sources(SampleSource a, SampleSource b);

}  // namespace sl::train
