// A learned detector of the sun's glare in an LDR photo (issue 53): where, if anywhere, the sun is
// in view. The hand-made cue (data/visible_sun.h) accepts a clipped blob by fixed thresholds on its
// size, roundness and halo; it misses the sun behind a lens flare's spikes or in haze, and its
// looser settings fire on white walls and clouds. This small network looks at the blob AND its
// surroundings and is trained on crops aimed at labelled suns and on crops without one.
//
// Input: glare_input(ldr [3, H, W]) → [4, 64, 128]: the image area-resampled to 64×128 (any H×W;
// each axis is scaled on its own), minus 0.5, and a fourth channel, the share of each resampled
// pixel's source pixels that are clipped (every channel ≥ 0.98, as data/visible_sun.h).
//
// Output: SunGlareDetector::forward(x [N, 4, 64, 128]) → logits [N, 1 + 16·32]. Index 0 is "no sun
// in view"; index 1 + r·32 + c is "the sun is in cell (r, c)" of a 16×32 grid over the image
// (cells of 4×4 input pixels). softmax gives one distribution over both.
//
// Training target: glare_target(pixel or none, H, W) → [1 + 512]: one-hot on index 0 without a sun;
// with one, a Gaussian over the cell centres around its pixel (σ = 0.75 cell), summing to 1. The
// loss is the cross-entropy of train/sun_distribution.h's sun_distribution_loss.
//
// Readout: read_glare(logits [1 + 512], H, W) → p_sun = 1 − softmax[0], and the pixel (continuous
// coordinates of the H×W image, render/camera.h) at the probability-weighted mean of the cell
// centres within one cell of the most probable cell.
//
// Azimuth head (optional, issue 53: front and back): with azimuth_bins A > 0 the detector also
// says where the sun is in AZIMUTH, in view or not, from the same features: forward_heads(x).azimuth
// → logits [N, A] over the sectors of the camera's canonical frame (train/street_batch.h: the camera
// looks at azimuth 0; sector j spans [−π + j·2π/A, −π + (j+1)·2π/A), as train/sun_distribution.h's
// sectors). It reads the crop's light at coarse resolution (the features average-pooled to 4×8
// cells), where backlit haze, the sky's brightness gradient and the shading of walls tell in
// front from behind. Trained by cross-entropy against azimuth_target. A detector without it
// (azimuth_bins 0, the 0.7.3 file) has the same parameters and outputs as before.
// - azimuth_target(A, φ, width_deg) → [A] probabilities ∝ exp(−Δ²/2σ²) over the sector centres,
//   Δ the wrapped difference to φ, σ = width_deg; sums to 1.
// - read_glare(logits, H, W, azimuth_logits) also fills GlareReading::azimuth with the softmax of
//   the azimuth logits (empty without them).
// - mirror_sectors(q): the sectors of the mirrored image (φ → −φ maps sector j to A − 1 − j).
// - read_glare_flip_averaged(detector, x [4, 64, 128], H, W, average_map): read_glare of x, with its
//   azimuth probabilities (with average_map, its cells too) averaged with those of x's mirror image,
//   mirrored back, as the sun head's flip averaging; p_sun and pixel stay x's own. One pass when
//   there is nothing to average (no azimuth head, no average_map).
//
// Glare map (issue 53: the sun in view that the threshold misses): below kGlareThreshold the
// detector's map still says where in the image a sun is likelier. glare_sky_factor turns it into
// a likelihood ratio over the cells of the sun head's grid (train/sun_distribution.h), which
// LightingEstimator multiplies in (weigh_by_cells) with exponent kGlareMapWeight.
// - GlareReading::cells: the softmax over the 1 + 16·32 outputs (index 0: no sun in view).
// - mirror_glare_cells(cells) → the cells of the mirrored image (column c → 31 − c; index 0 kept).
// - glare_sky_factor(grid, camera, cells) → [K]: for a sun-grid cell k that the centre rays of n_k
//   ≥ 1 glare cells fall in (camera: the view's camera in the sun grid's frame, i.e. the canonical
//   frame; rays below the horizon are dropped), (Σ_c q_c / n_k) / ((1 − π₀) / 512) divided by
//   q₀ / π₀: how much likelier the detector makes the sun there than its training prior did,
//   relative to the cells out of view, whose factor is 1. π₀ = kGlareNoSunPrior, the share of
//   the released detector's training crops without a sun in view. Finite and ≥ 0 for any cells of
//   finite values ≥ 0 (q₀ is floored at 1e-12); throws for cells not of 513 values; the camera's
//   image may have any size (the glare cells scale with it).
//
// Guarantees: every output finite for finite input (NaN/Inf pixels of the image read as 0);
// deterministic. Throws sl::Error for an input that is not [3, H, W] or [N, 4, 64, 128], or logits
// not of 513 values.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "nn/module.h"
#include "render/camera.h"
#include "train/sun_distribution.h"

namespace sl::train {

inline constexpr int kGlareInputHeight = 64, kGlareInputWidth = 128, kGlareCell = 4;
inline constexpr int kGlareRows = kGlareInputHeight / kGlareCell, kGlareCols = kGlareInputWidth / kGlareCell;
inline constexpr int kGlareOutputs = 1 + kGlareRows * kGlareCols;

// The probability of a sun in view above which the detector's answer is used (LightingEstimator):
// chosen on the validation split with `streetlight-bench sun-glare` (see models/MODEL_CARD.md).
inline constexpr double kGlareThreshold = 0.95;
// The exponent of the azimuth head's probabilities where they reweigh the sun head's distribution
// (train/sun_distribution.h, weigh_by_azimuth; LightingEstimator): chosen among 0, 0.5, 1 and 2 on
// the validation split with `streetlight-eval --glare-azimuth-weight` (models/README.md). 0 leaves
// the sun head's answer.
inline constexpr double kGlareAzimuthWeight = 0.5;

// The share of the released detector's training crops with no sun in view (13 652 of 18 984,
// models/README.md): the prior of glare_sky_factor.
inline constexpr double kGlareNoSunPrior = 0.719;
// The exponent of glare_sky_factor where it reweighs the sun head's distribution (LightingEstimator,
// weigh_by_cells); 0 leaves the sun head's answer.
inline constexpr double kGlareMapWeight = 0.0;

struct SunGlareOptions {
  int64_t width = 24;         // channels of the first layer; later layers use 2·width
  int64_t azimuth_bins = 0;   // sectors of the azimuth head; 0: no azimuth head
  // The negative slope of the azimuth head's hidden activation: 0 is a ReLU (the 0.7.4 file); > 0 a
  // leaky ReLU, whose units keep a gradient where they are negative and so cannot die for good.
  double azimuth_slope = 0.0;
  uint64_t seed = 1;
};

struct GlareHeads {
  Tensor glare;    // [N, 1 + 16·32]
  Tensor azimuth;  // [N, azimuth_bins]; undefined without the azimuth head
};

class SunGlareDetector : public nn::Module {
 public:
  explicit SunGlareDetector(SunGlareOptions options = {});
  Tensor forward(const Tensor& x) override;  // the glare logits only
  GlareHeads forward_heads(const Tensor& x);
  // What the azimuth head reads: the features average-pooled to 4×8 cells and flattened,
  // [N, 2·width·32] (for probes of what the detector knows; throws without an azimuth head).
  Tensor azimuth_features(const Tensor& x);
  // The azimuth head's hidden units after their ReLU, [N, 64]: a unit that is 0 on every crop is
  // dead, and a head whose units are all dead answers one constant (throws without an azimuth head).
  Tensor azimuth_hidden(const Tensor& x);
  const SunGlareOptions& options() const { return opt_; }
  bool has_azimuth() const { return opt_.azimuth_bins > 0; }

 private:
  SunGlareOptions opt_;
  std::shared_ptr<nn::Module> features_, cells_, none_, azimuth_pool_, azimuth_;
};

Tensor glare_input(const Tensor& ldr);
Tensor glare_target(const std::optional<glm::dvec2>& pixel, int height, int width);

std::vector<double> azimuth_target(int64_t bins, double azimuth_rad, double width_deg);
std::vector<double> mirror_sectors(const std::vector<double>& q);

struct GlareReading {
  double p_sun = 0.0;
  glm::dvec2 pixel{0.0};
  std::vector<double> azimuth;  // the azimuth head's probabilities per sector; empty without it
  std::vector<double> cells;    // softmax over the 1 + 16·32 outputs; index 0: no sun in view
};
GlareReading read_glare(const Tensor& logits, int height, int width, const Tensor& azimuth_logits = Tensor());

std::vector<double> mirror_glare_cells(const std::vector<double>& cells);
GlareReading read_glare_flip_averaged(SunGlareDetector& detector, const Tensor& input, int height, int width,
                                      bool average_map = false);
std::vector<double> glare_sky_factor(const SunGrid& grid, const render::Camera& camera, const std::vector<double>& cells);

// A detector from a checkpoint saved by `streetlight-bench sun-glare` (stage "sun_glare"; its
// config's "width" sizes the network, "azimuth_bins", when present, its azimuth head, and
// "azimuth_slope", when present, that head's activation), in eval mode. Throws sl::Error naming the
// file when it is not one.
std::shared_ptr<SunGlareDetector> load_sun_glare(const std::string& path);

}  // namespace sl::train
