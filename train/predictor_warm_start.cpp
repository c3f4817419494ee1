// Warm start of a lighting predictor from an earlier architecture. See predictor_warm_start.h.
#include "train/predictor_warm_start.h"

#include <algorithm>
#include <vector>

#include "nn/checkpoint.h"
#include "nn/safetensors.h"
#include "util/error.h"

namespace sl::train {

namespace {

class Holder : public nn::Module {
 public:
  Holder() : nn::Module("LightingModel") {}
};

// The batch norms whose channels are added to the residual stream: the stem's, each block's last
// and each shortcut's.
bool feeds_the_stream(const std::string& name) {
  return name.rfind("backbone.bn1.", 0) == 0 || name.find(".bn2.") != std::string::npos ||
         name.find(".downsample.1.") != std::string::npos;
}

// The new stream channels' constant value: positive, so the ReLUs after the sums pass gradients.
constexpr double kNewStreamValue = 1e-2;

// A backbone tensor of a narrower ResNet inside the wider one's: the loaded values in the leading
// corner (the old channels keep their indices), the rest from `fresh`, the wider model's own
// initialisation, except where the new channels could change the old answers or could not train:
// - no new input reaches an old output: every conv's weights from new input channels into old
//   output channels are 0;
// - a stream batch norm's new channels have scale 0 and shift kNewStreamValue, so the new stream
//   channels are a small positive constant (at exactly 0 the ReLU after each sum would pass no
//   gradient, and they would never train).
Tensor widen_backbone_tensor(const std::string& name, const Tensor& old, const Tensor& fresh) {
  const int64_t rank = old.dim();
  std::vector<double> w = fresh.to_vector();
  const std::vector<double> o = old.to_vector();
  const bool stream_scale = rank == 1 && feeds_the_stream(name) && name.ends_with(".weight");
  const bool stream_shift = rank == 1 && feeds_the_stream(name) && name.ends_with(".bias");
  const int64_t inner = rank == 4 ? fresh.size(2) * fresh.size(3) : 1;  // a conv's kernel taps
  for (int64_t r = 0; r < fresh.size(0); ++r) {
    if (rank == 1) {
      if (r < old.size(0)) w[r] = o[r];
      else if (stream_scale) w[r] = 0.0;
      else if (stream_shift) w[r] = kNewStreamValue;
      continue;
    }
    for (int64_t c = 0; c < fresh.size(1); ++c) {
      double* dst = w.data() + (r * fresh.size(1) + c) * inner;
      if (r < old.size(0) && c < old.size(1)) std::copy_n(o.data() + (r * old.size(1) + c) * inner, inner, dst);
      else if (r < old.size(0)) std::fill_n(dst, inner, 0.0);
    }
  }
  return Tensor::from_vector(w, fresh.shape(), fresh.dtype());
}

}  // namespace

bool warm_start_predictor(const std::string& path, const std::shared_ptr<LightingPredictor>& predictor,
                          const std::shared_ptr<SkyAutoencoder>& teacher) {
  bool has_teacher = false, has_sun_head = false, has_head_grid = false, has_third_block = false, has_sun_backbone = false,
       has_volume = false;
  int64_t sun_head_inputs = 0, stem_width = 0;
  for (const auto& [name, t] : nn::read_safetensors(path).tensors) {
    has_teacher |= name.rfind("teacher.", 0) == 0;
    has_sun_head |= name.rfind("predictor.sun_head.", 0) == 0;
    has_head_grid |= name.rfind("predictor.head_grid.", 0) == 0;
    has_sun_backbone |= name.rfind("predictor.sun_backbone.", 0) == 0;
    has_volume |= name.rfind("predictor.volume_mlp.", 0) == 0 || name.rfind("predictor.volume_unet.", 0) == 0;
    has_third_block |= name.rfind("predictor.backbone.layer1.2.", 0) == 0;  // ResNet-34's, not -18's
    if (name == "predictor.sun_head.net.0.weight") sun_head_inputs = t.size(1);
    if (name == "predictor.backbone.conv1.weight") stem_width = t.size(0);
  }
  // A model from before the sun head (model.sun_grid) starts one: everything else is loaded
  // into a predictor without it, then copied over; the new head keeps its initialisation.
  // A sun head from before model.sun_image_statistics is widened: its first layer keeps its
  // weights for the backbone's features and gets zeros for the statistics, so the model starts
  // from exactly the loaded one's answers. A model from before model.head_grid_channels gets the
  // grid the same way: every head that reads the features (sky, sun, volume MLP) keeps its
  // weights for the pooled vector and gets zeros for the grid, which follows it, and the grid's
  // 1×1 convolution keeps its initialisation. A ResNet-18 backbone deepens to a ResNet-34 the
  // same way: its blocks keep their places (layerK.0, layerK.1), and each new block starts with
  // its last batch norm's scale and shift at zero, so it adds nothing to its shortcut and, the
  // input being a ReLU's output, passes it on unchanged (the "zero-γ" residual initialisation).
  // A narrower backbone (model.backbone_width) widens: see widen_backbone_tensor; the heads get
  // zero columns for the new features. A sun head gains its own backbone (model.sun_backbone) the
  // same way: zero columns for its features, which come last; the backbone keeps its initialisation
  // (init.sun_backbone_weights, loaded after this, replaces it). A model trained without the volume
  // branch (model.volume_branch false: the backbone and the sky and sun heads alone, at less than half
  // the cost of a step) gains it: the volume MLP and 3D UNet keep their initialisation, and the sky's
  // answers are the loaded model's, since they do not read the volume.
  const LightingPredictorOptions& mine = predictor->options();
  std::shared_ptr<LightingPredictor> loaded = predictor;
  // The checkpoint's own architecture: this model's, less what the checkpoint does not have.
  LightingPredictorOptions without = mine;
  if (!has_sun_head) without.sun_grid = SunGrid{}, without.sun_image_statistics = false;
  if (!has_head_grid) without.head_grid_channels = 0;
  if (!has_sun_backbone) without.sun_backbone.clear();
  if (!has_volume) without.volume_branch = false;
  if (!has_third_block && mine.backbone_depth == 34) without.backbone_depth = 18;
  if (stem_width > 0 && stem_width < mine.backbone_width) {
    SL_CHECK(mine.head_grid_channels == 0 && !mine.sun_image_statistics, "init.checkpoint '", path,
             "': a wider model.backbone_width would put new features between the heads' columns for ",
             "model.head_grid_channels or model.sun_image_statistics; widen a model without them");
    without.backbone_width = stem_width;
  }
  if (has_sun_head && without.sun_image_statistics) {
    LightingPredictorOptions plain = without;
    plain.sun_image_statistics = false;
    without.sun_image_statistics = LightingPredictor(plain).state_dict().at("sun_head.net.0.weight").size(1) != sun_head_inputs;
  }
  SL_CHECK(has_head_grid || mine.head_grid_channels == 0 || !without.sun_image_statistics, "init.checkpoint '", path,
           "': its sun head reads image statistics, and a new model.head_grid_channels would go between its columns; ",
           "start the grid from a model without model.sun_image_statistics");
  if (without.sun_grid.enabled() != mine.sun_grid.enabled() || without.head_grid_channels != mine.head_grid_channels ||
      without.sun_image_statistics != mine.sun_image_statistics || without.backbone_depth != mine.backbone_depth ||
      without.backbone_width != mine.backbone_width || without.sun_backbone != mine.sun_backbone ||
      without.volume_branch != mine.volume_branch)
    loaded = std::make_shared<LightingPredictor>(without);
  Holder previous;
  previous.register_module("predictor", loaded);
  if (teacher && has_teacher) previous.register_module("teacher", teacher);
  nn::load_checkpoint(path, previous, nullptr);
  if (loaded != predictor) {
    nn::StateDict merged = predictor->state_dict();
    for (auto& [name, t] : merged) t = t.clone();
    if (without.backbone_depth != mine.backbone_depth) {
      const nn::StateDict old = loaded->state_dict();
      for (auto& [name, t] : merged)
        if (name.rfind("backbone.layer", 0) == 0 && (name.ends_with(".bn2.weight") || name.ends_with(".bn2.bias")) &&
            !old.count(name))
          t = Tensor::zeros(t.shape(), t.dtype());
    }
    for (const auto& [name, t] : loaded->state_dict()) {
      Tensor& into = merged.at(name);
      if (into.shape() == t.shape()) {
        into = t;
        continue;
      }
      if (name.rfind("backbone.", 0) == 0 && without.backbone_width != mine.backbone_width && into.dim() == t.dim()) {
        into = widen_backbone_tensor(name, t, into);
        continue;
      }
      // A widened first layer [out, in + new inputs]: the loaded columns, then zeros.
      SL_CHECK(name.ends_with(".net.0.weight") && t.dim() == 2 &&
                   into.dim() == 2 && into.size(0) == t.size(0) && into.size(1) > t.size(1),
               "init.checkpoint '", path, "': ", name, " is ", t.describe(), ", the model's is ", into.describe());
      std::vector<double> w(static_cast<size_t>(into.numel()), 0.0);
      const std::vector<double> old = t.to_vector();
      for (int64_t r = 0; r < t.size(0); ++r)
        std::copy_n(old.begin() + r * t.size(1), t.size(1), w.begin() + r * into.size(1));
      into = Tensor::from_vector(w, into.shape(), into.dtype());
    }
    predictor->load_state_dict(merged);
  }
  return has_teacher;
}

}  // namespace sl::train
