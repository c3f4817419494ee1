// The learned sun-glare detector. See sun_glare.h.
#include "train/sun_glare.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "data/panorama.h"
#include "nn/checkpoint.h"
#include "nn/layers.h"
#include <nlohmann/json.hpp>
#include "util/error.h"
#include "util/math.h"

namespace sl::train {

namespace {
constexpr double kClipLevel = 0.98;  // data/visible_sun.h's saturation
constexpr double kTargetSigmaCells = 0.75;
}  // namespace

SunGlareDetector::SunGlareDetector(SunGlareOptions options) : nn::Module("SunGlareDetector"), opt_(options) {
  SL_CHECK(opt_.width >= 1 && opt_.width <= 256, "SunGlareDetector: width must be in [1, 256], got ", opt_.width);
  const int64_t w = opt_.width, w2 = 2 * opt_.width;
  auto relu = [] { return std::make_shared<nn::ReLU>(); };
  // 64×128 → 32×64 → 16×32, then two dilated layers that see about a quarter of the image around
  // each cell: the glare's surroundings (sky or wall) decide as much as the blob does.
  features_ = register_module(
      "features", std::make_shared<nn::Sequential>(std::vector<std::shared_ptr<nn::Module>>{
                      std::make_shared<nn::Conv2d>(4, w, 3, nn::ConvOptions{.padding = 1}), relu(),
                      std::make_shared<nn::Conv2d>(w, w2, 3, nn::ConvOptions{.stride = 2, .padding = 1}), relu(),
                      std::make_shared<nn::Conv2d>(w2, w2, 3, nn::ConvOptions{.padding = 1}), relu(),
                      std::make_shared<nn::Conv2d>(w2, w2, 3, nn::ConvOptions{.stride = 2, .padding = 1}), relu(),
                      std::make_shared<nn::Conv2d>(w2, w2, 3, nn::ConvOptions{.padding = 2, .dilation = 2}), relu(),
                      std::make_shared<nn::Conv2d>(w2, w2, 3, nn::ConvOptions{.padding = 4, .dilation = 4}), relu()}));
  cells_ = register_module("cells", std::make_shared<nn::Conv2d>(w2, 1, 1));
  none_ = register_module("none", std::make_shared<nn::Linear>(2 * w2, 1));
  SL_CHECK(opt_.azimuth_bins >= 0 && opt_.azimuth_bins <= 360, "SunGlareDetector: azimuth_bins must be in [0, 360], got ",
           opt_.azimuth_bins);
  SL_CHECK(std::isfinite(opt_.azimuth_slope) && opt_.azimuth_slope >= 0.0 && opt_.azimuth_slope < 1.0,
           "SunGlareDetector: azimuth_slope must be in [0, 1), got ", opt_.azimuth_slope);
  if (has_azimuth()) {
    // The features at 4×8 cells: where in the view it is bright, hazy or shaded, not the blob.
    azimuth_pool_ = register_module("azimuth_pool", std::make_shared<nn::AvgPool2d>(4));
    azimuth_ = register_module("azimuth", std::make_shared<nn::Sequential>(std::vector<std::shared_ptr<nn::Module>>{
                                              std::make_shared<nn::Linear>(w2 * 32, 64),
                                              opt_.azimuth_slope > 0.0 ? std::shared_ptr<nn::Module>(std::make_shared<nn::LeakyReLU>(opt_.azimuth_slope))
                                                                       : std::shared_ptr<nn::Module>(relu()),
                                              std::make_shared<nn::Linear>(64, opt_.azimuth_bins)}));
  }
  init_parameters(opt_.seed);
}

Tensor SunGlareDetector::forward(const Tensor& x) { return forward_heads(x).glare; }

Tensor SunGlareDetector::azimuth_features(const Tensor& x) {
  SL_CHECK(has_azimuth(), "SunGlareDetector::azimuth_features: this detector has no azimuth head");
  SL_CHECK(x.defined() && x.dim() == 4 && x.size(1) == 4 && x.size(2) == kGlareInputHeight && x.size(3) == kGlareInputWidth,
           "SunGlareDetector: expected [N, 4, 64, 128], got ", x.defined() ? x.describe() : std::string("undefined"));
  const Tensor f = features_->forward(x);
  return reshape(azimuth_pool_->forward(f), {x.size(0), f.size(1) * 32});
}

Tensor SunGlareDetector::azimuth_hidden(const Tensor& x) {
  const Tensor f = azimuth_features(x);  // throws without an azimuth head
  const auto& head = static_cast<const nn::Sequential&>(*azimuth_);
  return head[1]->forward(head[0]->forward(f));
}

GlareHeads SunGlareDetector::forward_heads(const Tensor& x) {
  SL_CHECK(x.defined() && x.dim() == 4 && x.size(1) == 4 && x.size(2) == kGlareInputHeight && x.size(3) == kGlareInputWidth,
           "SunGlareDetector: expected [N, 4, 64, 128], got ", x.defined() ? x.describe() : std::string("undefined"));
  const int64_t n = x.size(0);
  const Tensor f = features_->forward(x);                                   // [N, 2w, 16, 32]
  const Tensor cells = reshape(cells_->forward(f), {n, kGlareRows * kGlareCols});
  const Tensor pooled = concat({mean(f, {2, 3}), max(f, {2, 3})}, 1);     // [N, 4w]
  const Tensor none = none_->forward(pooled);                               // [N, 1]
  GlareHeads out;
  out.glare = concat({none, cells}, 1);
  if (has_azimuth()) out.azimuth = azimuth_->forward(reshape(azimuth_pool_->forward(f), {n, f.size(1) * 32}));  // as azimuth_features
  return out;
}

std::vector<double> azimuth_target(int64_t bins, double azimuth_rad, double width_deg) {
  SL_CHECK(bins > 0, "azimuth_target: bins must be positive, got ", bins);
  SL_CHECK(std::isfinite(azimuth_rad), "azimuth_target: the azimuth is not finite");
  SL_CHECK(std::isfinite(width_deg) && width_deg > 0.0, "azimuth_target: width_deg must be positive, got ", width_deg);
  const double sigma = width_deg * kPi / 180.0;
  std::vector<double> t(static_cast<size_t>(bins));
  double total = 0.0;
  for (int64_t j = 0; j < bins; ++j) {
    const double centre = -kPi + (double(j) + 0.5) * 2.0 * kPi / double(bins);
    const double d = std::remainder(centre - azimuth_rad, 2.0 * kPi);
    total += t[size_t(j)] = std::exp(-0.5 * d * d / (sigma * sigma));
  }
  if (!(total > 0.0)) {  // narrower than a sector: the sector holding it
    std::fill(t.begin(), t.end(), 0.0);
    const double u = (std::remainder(azimuth_rad, 2.0 * kPi) + kPi) / (2.0 * kPi) * double(bins);
    t[size_t(std::clamp<int64_t>(int64_t(std::floor(u)), 0, bins - 1))] = 1.0;
    return t;
  }
  for (double& v : t) v /= total;
  return t;
}

std::vector<double> mirror_sectors(const std::vector<double>& q) { return {q.rbegin(), q.rend()}; }

Tensor glare_input(const Tensor& ldr) {
  SL_CHECK(ldr.defined() && ldr.dim() == 3 && ldr.size(0) == 3 && ldr.size(1) > 0 && ldr.size(2) > 0,
           "glare_input: expected an LDR image [3, H, W], got ", ldr.defined() ? ldr.describe() : std::string("undefined"));
  const int64_t h = ldr.size(1), w = ldr.size(2), plane = h * w;
  const Tensor c = ldr.detach().to(DType::F32).contiguous();
  Tensor four = Tensor::zeros({4, h, w}, DType::F32);
  const float* p = c.data<float>();
  float* q = four.data<float>();
  for (int64_t i = 0; i < plane; ++i) {
    float lo = 1.0f;
    for (int ch = 0; ch < 3; ++ch) {
      const float v = std::isfinite(p[ch * plane + i]) ? std::clamp(p[ch * plane + i], 0.0f, 1.0f) : 0.0f;
      q[ch * plane + i] = v;
      lo = std::min(lo, v);
    }
    q[3 * plane + i] = lo >= kClipLevel ? 1.0f : 0.0f;
  }
  Tensor small = data::resize_area(four, kGlareInputHeight, kGlareInputWidth).contiguous();
  float* s = small.data<float>();
  for (int64_t i = 0; i < 3 * int64_t(kGlareInputHeight) * kGlareInputWidth; ++i) s[i] -= 0.5f;
  return small;
}

Tensor glare_target(const std::optional<glm::dvec2>& pixel, int height, int width) {
  SL_CHECK(height > 0 && width > 0, "glare_target: image size must be positive, got ", width, "x", height);
  Tensor t = Tensor::zeros({kGlareOutputs}, DType::F32);
  float* p = t.data<float>();
  if (!pixel) {
    p[0] = 1.0f;
    return t;
  }
  // The pixel in cell units of the grid.
  const double cu = pixel->x / width * kGlareCols, cv = pixel->y / height * kGlareRows;
  double total = 0.0;
  std::vector<double> g(kGlareRows * kGlareCols, 0.0);
  for (int r = 0; r < kGlareRows; ++r)
    for (int c = 0; c < kGlareCols; ++c) {
      const double du = c + 0.5 - cu, dv = r + 0.5 - cv;
      g[r * kGlareCols + c] = std::exp(-0.5 * (du * du + dv * dv) / (kTargetSigmaCells * kTargetSigmaCells));
      total += g[r * kGlareCols + c];
    }
  if (!(total > 0.0)) {  // far outside the image: the nearest cell
    const int r = std::clamp(int(cv), 0, kGlareRows - 1), c = std::clamp(int(cu), 0, kGlareCols - 1);
    p[1 + r * kGlareCols + c] = 1.0f;
    return t;
  }
  for (size_t k = 0; k < g.size(); ++k) p[1 + k] = float(g[k] / total);
  return t;
}

GlareReading read_glare(const Tensor& logits, int height, int width, const Tensor& azimuth_logits) {
  SL_CHECK(logits.defined() && logits.numel() == kGlareOutputs, "read_glare: expected ", kGlareOutputs, " logits, got ",
           logits.defined() ? logits.describe() : std::string("undefined"));
  const Tensor l = logits.detach().to(DType::F64).contiguous();
  const double* x = l.data<double>();
  double top = -1e300;
  for (int k = 0; k < kGlareOutputs; ++k)
    if (std::isfinite(x[k])) top = std::max(top, x[k]);
  std::vector<double> p(kGlareOutputs, 0.0);
  double total = 0.0;
  for (int k = 0; k < kGlareOutputs; ++k) total += p[k] = std::isfinite(x[k]) ? std::exp(x[k] - top) : 0.0;
  GlareReading out;
  if (!(total > 0.0)) return out;
  for (double& v : p) v /= total;
  out.cells = p;
  out.p_sun = std::clamp(1.0 - p[0], 0.0, 1.0);
  int best = 1;
  for (int k = 2; k < kGlareOutputs; ++k)
    if (p[k] > p[best]) best = k;
  const int br = (best - 1) / kGlareCols, bc = (best - 1) % kGlareCols;
  double su = 0.0, sv = 0.0, sw = 0.0;
  for (int r = std::max(0, br - 1); r <= std::min(kGlareRows - 1, br + 1); ++r)
    for (int c = std::max(0, bc - 1); c <= std::min(kGlareCols - 1, bc + 1); ++c) {
      const double w = p[1 + r * kGlareCols + c];
      su += w * (c + 0.5), sv += w * (r + 0.5), sw += w;
    }
  const double u = sw > 0.0 ? su / sw : bc + 0.5, v = sw > 0.0 ? sv / sw : br + 0.5;
  out.pixel = {u / kGlareCols * width, v / kGlareRows * height};
  if (azimuth_logits.defined()) {
    std::vector<double> z = azimuth_logits.detach().to(DType::F64).contiguous().to_vector();
    for (double& v : z)
      if (!std::isfinite(v)) v = -1e300;
    double m = -1e300, s = 0.0;
    for (const double v : z) m = std::max(m, v);
    out.azimuth.resize(z.size());
    for (size_t k = 0; k < z.size(); ++k) s += out.azimuth[k] = std::exp(z[k] - m);
    for (double& v : out.azimuth) v = s > 0.0 ? v / s : 1.0 / double(z.size());
  }
  return out;
}

std::vector<double> mirror_glare_cells(const std::vector<double>& cells) {
  SL_CHECK(cells.size() == size_t(kGlareOutputs), "mirror_glare_cells: expected ", kGlareOutputs, " values, got ",
           cells.size());
  std::vector<double> out(cells.size());
  out[0] = cells[0];
  for (int r = 0; r < kGlareRows; ++r)
    for (int c = 0; c < kGlareCols; ++c) out[size_t(1 + r * kGlareCols + (kGlareCols - 1 - c))] = cells[size_t(1 + r * kGlareCols + c)];
  return out;
}

GlareReading read_glare_flip_averaged(SunGlareDetector& detector, const Tensor& input, int height, int width,
                                      bool average_map) {
  SL_CHECK(input.dim() == 3 && input.size(0) == 4 && input.size(1) == kGlareInputHeight && input.size(2) == kGlareInputWidth,
           "read_glare_flip_averaged: expected an input [4, ", kGlareInputHeight, ", ", kGlareInputWidth, "], got ",
           input.describe());
  const GlareHeads h = detector.forward_heads(unsqueeze(input, 0));
  const auto azimuth_of = [](const GlareHeads& g) { return g.azimuth.defined() ? select(g.azimuth, 0, 0) : Tensor(); };
  GlareReading out = read_glare(select(h.glare, 0, 0), height, width, azimuth_of(h));
  if (!h.azimuth.defined() && !average_map) return out;
  const GlareHeads m = detector.forward_heads(unsqueeze(data::flip_horizontal(input), 0));
  const GlareReading mr = read_glare(select(m.glare, 0, 0), height, width, azimuth_of(m));
  if (h.azimuth.defined()) {
    const std::vector<double> mq = mirror_sectors(mr.azimuth);
    for (size_t j = 0; j < out.azimuth.size(); ++j) out.azimuth[j] = 0.5 * (out.azimuth[j] + mq[j]);
  }
  if (average_map && !out.cells.empty() && !mr.cells.empty()) {
    const std::vector<double> mc = mirror_glare_cells(mr.cells);
    for (size_t j = 0; j < out.cells.size(); ++j) out.cells[j] = 0.5 * (out.cells[j] + mc[j]);
  }
  return out;
}

std::vector<double> glare_sky_factor(const SunGrid& grid, const render::Camera& camera, const std::vector<double>& cells) {
  validate(grid);
  SL_CHECK(grid.enabled(), "glare_sky_factor: the sun grid is off");
  SL_CHECK(cells.size() == size_t(kGlareOutputs), "glare_sky_factor: expected ", kGlareOutputs, " values, got ",
           cells.size());
  for (const double v : cells) SL_CHECK(std::isfinite(v) && v >= 0.0, "glare_sky_factor: a value is not finite and >= 0 (", v, ")");
  const double w = camera.intrinsics().width, h = camera.intrinsics().height;
  std::vector<double> sum(size_t(grid.cells()), 0.0), count(size_t(grid.cells()), 0.0);
  for (int r = 0; r < kGlareRows; ++r)
    for (int c = 0; c < kGlareCols; ++c) {
      const glm::dvec3 d = camera.ray((c + 0.5) / kGlareCols * w, (r + 0.5) / kGlareRows * h).direction;
      const int64_t k = cell_of_direction(grid, d);
      if (k < 0) continue;
      sum[size_t(k)] += cells[size_t(1 + r * kGlareCols + c)];
      count[size_t(k)] += 1.0;
    }
  // The detector's posterior over a region against its training prior, over that ratio for the
  // region out of view: (q_in / π_in) / (q₀ / π₀), with π_in = (1 − π₀)·n/512 for n glare cells.
  const double out_of_view = std::max(cells[0], 1e-12) / kGlareNoSunPrior;
  const double per_cell_prior = (1.0 - kGlareNoSunPrior) / double(kGlareRows * kGlareCols);
  std::vector<double> f(size_t(grid.cells()), 1.0);
  for (size_t k = 0; k < f.size(); ++k)
    if (count[k] > 0.0) f[k] = sum[k] / count[k] / per_cell_prior / out_of_view;
  return f;
}

std::shared_ptr<SunGlareDetector> load_sun_glare(const std::string& path) {
  const nn::CheckpointInfo info = nn::read_checkpoint_info(path);
  SL_CHECK(info.stage == "sun_glare", "load_sun_glare: '", path, "' is a '", info.stage,
           "' checkpoint, not a sun-glare detector");
  const nlohmann::json cfg = nlohmann::json::parse(info.config_json, nullptr, false);
  SL_CHECK(!cfg.is_discarded() && cfg.contains("width") && cfg["width"].is_number_integer(), "load_sun_glare: '", path,
           "' has no integer config key 'width'");
  int64_t bins = 0;
  if (cfg.contains("azimuth_bins")) {
    SL_CHECK(cfg["azimuth_bins"].is_number_integer() && cfg["azimuth_bins"].get<int64_t>() >= 0 &&
                 cfg["azimuth_bins"].get<int64_t>() <= 360,
             "load_sun_glare: '", path, "' has config key 'azimuth_bins' that is not an integer in [0, 360]");
    bins = cfg["azimuth_bins"].get<int64_t>();
  }
  double slope = 0.0;
  if (cfg.contains("azimuth_slope")) {
    SL_CHECK(cfg["azimuth_slope"].is_number() && cfg["azimuth_slope"].get<double>() >= 0.0 &&
                 cfg["azimuth_slope"].get<double>() < 1.0,
             "load_sun_glare: '", path, "' has config key 'azimuth_slope' that is not a number in [0, 1)");
    slope = cfg["azimuth_slope"].get<double>();
  }
  auto net = std::make_shared<SunGlareDetector>(
      SunGlareOptions{.width = cfg["width"].get<int64_t>(), .azimuth_bins = bins, .azimuth_slope = slope, .seed = 1});
  nn::load_checkpoint(path, *net, nullptr);
  net->eval();
  return net;
}

}  // namespace sl::train
