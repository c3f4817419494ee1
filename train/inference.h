// Lighting inference from a trained checkpoint: photo (+ depth + camera) → the hybrid lighting
// of Sec 3.2 (HDR sky dome + VSG volume), with sun editing (Sec 3.2) and multi-view fusion
// (Sec 4.1). Used by streetlight-insert and streetlight-eval.
//
// Frames (street_batch.h): the predictor works in the CANONICAL frame of its input camera —
// the world rotated about +Y so that camera looks at azimuth 0 (−Z) and translated so it sits at
// (0, y_cam, 0). The estimate below keeps everything in the canonical frame of the FIRST view
// (`frame`) and converts explicitly: world_direction()/world_point() go canonical → world,
// frame.direction()/frame.point() go world → canonical; env_world() is the dome rolled back to
// the world's azimuths. Insertion must therefore be done in the canonical frame (camera via
// frame.camera(), object position via frame.point(), yaw minus frame.yaw_rad).
//
// Contract:
// - LightingEstimator(path) loads a stage-2 or stage-3 checkpoint (predictor.* with its frozen
//   sky decoder; teacher.* and discriminator.* are ignored). Throws sl::Error naming the file
//   when it is not a lighting checkpoint or does not match its stored config.
// - estimate(views, edit): views[k] = LDR photo [3, H, W] in [0, 1] (the paper's LDR; an 8-bit
//   photo read without an sRGB curve), depth [H, W] (camera z, metres, holes 0/NaN/inf; may be
//   undefined for the sky-only branch), and the camera (world frame, intrinsics matching H×W).
//   One view: the predictor's output. Several views (Sec 4.1): each is predicted in its own
//   canonical frame, then the sky vectors are fused — element-wise max of log intensity and of
//   the latent, directions rotated into view 0's frame and averaged — and decoded once; the
//   volumes are resampled onto view 0's grid (nearest voxel, lobe axes rotated) and fused by
//   alpha-weighted averaging of colour, axis and sharpness with the maximum alpha.
// - SunEdit (Sec 3.2): replaces f̂_dir by the world direction of (azimuth, elevation) and/or
//   multiplies f̂_intensity by intensity_scale before decoding. Requires the "sky_decoder"
//   branch (throws otherwise). The volume is left as predicted.
// - Visible sun (set_visible_sun, on by default; issue 39 item 3): a network that has to guess
//   the sun from shading turns a sun it can SEE around. Each view's LDR goes through
//   data/visible_sun.h; when a sun disk is found (the view with the highest score wins), the
//   ray through its pixel (the view's camera) becomes the sun direction, through the SunEdit
//   path: its azimuth and elevation fill the fields the caller's SunEdit leaves unset, so an
//   explicit edit still wins field by field. Checkpoints without a sky vector ignore the cue.
//   When nothing is found the estimate is bit-identical to the cue being off.
// - Learned sun glare (set_sun_glare, off until a detector is given; the tools give the released
//   models/sun_glare.safetensors): where the disk test finds no sun in any view, the learned
//   detector (train/sun_glare.h) decides: the view with the highest probability of a sun in view
//   wins when it reaches the threshold, and the ray through its pixel is the sun as above
//   (visible_sun_learned, visible_sun_score = that probability). It runs as its own task of the
//   team beside the disk test (about 3 ms of one thread per view). When it does not fire, has no
//   azimuth head and its map weight is 0 (the default), the estimate is bit-identical to having no
//   detector. A detector with an azimuth head also reweighs the sun head's distribution by its
//   azimuth probabilities (see set_sun_glare; glare_azimuth_used), in every view: a second opinion
//   on front and back. With a map weight > 0 its glare map reweighs the distribution too, below the
//   threshold (glare_map_used).
// - Crop averaging (set_crop_scales, off by default): each view's sun also averaged over centred
//   crops of it; see set_crop_scales. Off, the estimate is bit-identical to before it existed.
// - Sun distribution (checkpoints with model.sun_grid, issue 53): the sky vector's direction is
//   the mode of the sun head's distribution, refined locally (train/sun_distribution.h), with
//   flip and crop averaging done on the probabilities; the sky head's own direction is unused.
// - Deterministic; no tape (runs under NoGradGuard).
// - Threads (issue 52): estimate() opens ONE OpenMP team whose tasks are each view's RGBα
//   unprojection, its mirror image's backbone pass, the visible-sun cue and each view's 3D UNet,
//   beside the photo's own pass; every loop inside runs on the thread of its task, and the fusion
//   and decoding after the team on the calling thread (util/parallel.h, SerialLoops). So a loaded
//   machine costs it at most a few scheduler waits, not one per op. The result is the same bits
//   for any thread count, and the same as the plain sequence of predictor calls
//   (tests/train/inference_test.cpp). Only the dome of the fused sky vector is decoded.
#pragma once
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "autodiff/tensor.h"
#include "data/sun_from_shadows.h"
#include "data/visible_sun.h"
#include "render/camera.h"
#include "render/radiance_query.h"
#include "render/vsg_volume.h"
#include "train/lighting_predictor.h"
#include "train/street_batch.h"
#include "train/sun_glare.h"

namespace sl::train {

struct InferenceView {
  Tensor ldr;    // [3, H, W] in [0, 1]
  Tensor depth;  // [H, W] metres, camera z
  render::Camera camera;  // world frame
};

struct SunEdit {
  std::optional<double> azimuth_deg, elevation_deg;  // world frame (render/equirect.h)
  double intensity_scale = 1.0;
  bool active() const { return azimuth_deg || elevation_deg || intensity_scale != 1.0; }
};

struct EstimatedLighting {
  CanonicalFrame frame;  // canonical frame of view 0
  render::Camera camera;  // view 0's camera in that frame
  Tensor env;            // [3, Hs, Ws] sky dome, canonical frame, exposure-normalised radiance
  Tensor vsg;            // [8, X, Y, Z] activated, or undefined (sky-only)
  render::VsgGrid grid;  // centred on view 0's canonical camera
  bool has_sky_code = false;
  glm::dvec3 sun_direction_canonical{0.0, 1.0, 0.0};
  glm::dvec3 sun_intensity_rgb{0.0};  // f_intensity (0 without a sky code: see sun_from_env)
  SkyCode sky_code;                   // the sky vector decoded into env ([1, ·] F32; has_sky_code only)
  double inference_ms = 0.0;          // predictor forward(s) + decoding, wall clock
  // A per-estimate confidence of the network's sun (flip averaging, sky-vector checkpoints): the
  // angle in degrees between the sun of the photo's pass and the mirror image of the mirrored
  // photo's pass, before the two are averaged. A network that reads the sun from the photo
  // finds it in both; a guess need not agree with its mirror image. The largest over the views;
  // the network's own even when a SunEdit replaces the direction. NaN when not measured (flip
  // averaging off, or no sky vector).
  // When the visible-sun cue sets the direction (visible_sun_found and the caller's SunEdit names
  // neither azimuth nor elevation) the direction was measured in the photo, not guessed: the
  // spread is then 0, so consumers that rank estimates by it (streetlight-eval's confident half)
  // rank these first; the network's own spread stays in network_sun_flip_spread_deg.
  double sun_flip_spread_deg = std::numeric_limits<double>::quiet_NaN();
  double network_sun_flip_spread_deg = std::numeric_limits<double>::quiet_NaN();
  // A third confidence, from crop averaging (LightingEstimator::set_crop_scales): the largest angle
  // in degrees between the photo's sun and a centred crop's (each flip-averaged when flip averaging
  // is on), the largest over the views. A sun read from the photo survives cropping; a guess moves
  // with what the crop leaves out. NaN when crop averaging is off or there is no sky vector; 0 when
  // the visible-sun cue set the direction (as for the flip spread), the network's own in
  // network_sun_crop_spread_deg.
  double sun_crop_spread_deg = std::numeric_limits<double>::quiet_NaN();
  double network_sun_crop_spread_deg = std::numeric_limits<double>::quiet_NaN();
  // A second confidence: how high the network put its sun, sin(elevation) in view 0's canonical
  // frame clamped to [0, 1], before any edit. Trained with an angular L1 loss, the network puts
  // a sun whose azimuth it cannot tell near the zenith (the direction nearest, on average, to
  // every azimuth), so a high sun is a hedge. 0 when the visible-sun cue set the direction (as
  // for the spread). Smaller is more confident; a true noon sun is ranked uncertain even when
  // right. Neither measure ranks errors reliably yet (docs/RESULTS.md, "Which confidence"):
  // streetlight-eval reports both. NaN without a sky vector.
  double sun_hedge = std::numeric_limits<double>::quiet_NaN();
  // The confidence of a checkpoint with a sun head (model.sun_grid, train/sun_distribution.h;
  // issue 53): the probability the network puts within 20° of its sun, in [0, 1] (LARGER is more
  // confident, unlike the spreads), after flip and crop averaging, the smallest over the views.
  // 1 when the visible-sun cue set the direction; the network's own in network_sun_probability.
  // NaN for checkpoints without a sun head.
  double sun_probability = std::numeric_limits<double>::quiet_NaN();
  double network_sun_probability = std::numeric_limits<double>::quiet_NaN();
  // The visible-sun cue (see LightingEstimator::set_visible_sun): whether it found a sun disk,
  // in which view, where (continuous pixel coordinates of that view's image, render/camera.h)
  // and its score (data/visible_sun.h). False when the cue is off or the checkpoint has no sky
  // vector.
  // visible_sun_learned: found by the learned glare detector (train/sun_glare.h), not the disk test;
  // visible_sun_score is then its probability of a sun in view.
  bool visible_sun_found = false;
  bool visible_sun_learned = false;
  // Whether the glare detector's azimuth head reweighed the sun head's distribution (see
  // LightingEstimator::set_sun_glare); sun_probability is then read from the reweighed one.
  bool glare_azimuth_used = false;
  // Whether the glare detector's map reweighed it (set_sun_glare's map_weight > 0).
  bool glare_map_used = false;
  int visible_sun_view = -1;
  glm::dvec2 visible_sun_pixel{0.0};
  double visible_sun_score = 0.0;

  glm::dvec3 world_direction(const glm::dvec3& canonical) const;
  glm::dvec3 world_point(const glm::dvec3& canonical) const;
  glm::dvec3 sun_direction_world() const { return world_direction(sun_direction_canonical); }
  Tensor env_world() const;
};

class LightingEstimator {
 public:
  explicit LightingEstimator(const std::string& checkpoint_path);
  EstimatedLighting estimate(const std::vector<InferenceView>& views, const SunEdit& edit = {});

  const nlohmann::json& config() const { return config_; }
  const std::string& path() const { return path_; }
  const std::string& stage() const { return stage_; }
  int64_t step() const { return step_; }
  render::RadianceQueryOptions volume_query() const;  // model.volume: K of Eq. 1, its spacing and lookup
  LightingPredictor& predictor() { return *predictor_; }
  // Flip averaging of the sun (sky-vector checkpoints): each view is also predicted mirrored
  // left-right, and its sun direction and log intensity are averaged with the mirror image of the
  // mirrored view's ((x, y, z) → (−x, y, z) in the canonical frame, exact for a level camera).
  // The latent stays the unflipped view's. One more backbone pass per view. On by default: with
  // release 0.2.0 (2026-11-25) it lowered the median sun error on the validation streets
  // (stage 2 19.2 -> 18.7 deg, stage 3 20.0 -> 19.7) and on the 320 held-out ones (19.7 -> 18.2,
  // 19.2 -> 18.3). Release 0.3.0, trained on mirrored streets, gains only in the mean
  // (stage 2: median 16.3 -> 16.5, mean 22.6 -> 21.8; stage 3: 16.6 -> 15.5; docs/RESULTS.md).
  void set_flip_average(bool on) { flip_average_ = on; }
  bool flip_average() const { return flip_average_; }
  // Crop averaging of the sun (sky-vector checkpoints): the centred crops of each view at these
  // scales (a fraction of its width and height, with equal margins, resized to the network's
  // input) are estimated as the view itself is (flip-averaged when flip averaging is on), and the
  // view's sun is the normalised sum of the unit suns of the view and its crops. Log intensity and
  // latent stay the view's own. Two more backbone passes per scale with flip averaging, one
  // without. Off (empty) by default: with the released model, {0.55, 0.7, 0.85} (chosen on the
  // validation splits) lowered the median sun error on validation (HDR 64.2° → 59.6°, LDR 58.5° →
  // 49.3°, 128 crops each) but raised it on the test splits (HDR 39.1° → 40.7°, LDR 43.7° → 46.0°;
  // docs/RESULTS.md, 2026-11-27), so it is measured, not a default. Its crop spread
  // (EstimatedLighting::sun_crop_spread_deg) is a third confidence. Throws sl::Error for a scale
  // outside (0, 1).
  void set_crop_scales(std::vector<double> scales);
  const std::vector<double>& crop_scales() const { return crop_scales_; }
  // The visible-sun cue (see the contract above) and its detector's thresholds.
  void set_visible_sun(bool on) { visible_sun_ = on; }
  bool visible_sun() const { return visible_sun_; }
  void set_visible_sun_params(const data::VisibleSunParams& p) { visible_sun_params_ = p; }
  const data::VisibleSunParams& visible_sun_params() const { return visible_sun_params_; }
  // The learned glare detector behind the disk test (null: none) and its probability threshold in
  // (0, 1] (throws outside).
  // With an azimuth head (train/sun_glare.h), its flip-averaged azimuth probabilities reweigh the
  // sun head's distribution before its mode is read (train/sun_distribution.h, weigh_by_azimuth,
  // raised to azimuth_weight; 0 turns it off), in every view, whether or not the sun is in view.
  // With map_weight > 0, the glare map, averaged with the mirror image's, reweighs it too
  // (train/sun_glare.h glare_sky_factor, weigh_by_cells, raised to map_weight), after the azimuth
  // head; the threshold's answer still wins where it fires. Throws for a weight that is negative
  // or not finite.
  void set_sun_glare(std::shared_ptr<SunGlareDetector> detector, double threshold = kGlareThreshold,
                     double azimuth_weight = kGlareAzimuthWeight, double map_weight = kGlareMapWeight);
  double sun_glare_azimuth_weight() const { return sun_glare_azimuth_weight_; }
  double sun_glare_map_weight() const { return sun_glare_map_weight_; }
  const std::shared_ptr<SunGlareDetector>& sun_glare() const { return sun_glare_; }

 private:
  struct Single {
    CanonicalFrame frame;
    render::Camera camera;
    render::VsgGrid grid;
    LightingPrediction pred;
    double flip_spread_deg = std::numeric_limits<double>::quiet_NaN();  // see EstimatedLighting
    double crop_spread_deg = std::numeric_limits<double>::quiet_NaN();  // see EstimatedLighting
    double sun_probability = std::numeric_limits<double>::quiet_NaN();  // see EstimatedLighting
    std::vector<double> glare_azimuth;  // the glare detector's azimuth probabilities (empty: none)
    bool glare_azimuth_used = false;
    std::vector<double> glare_cells;  // the glare map, flip-averaged (empty: not used)
    bool glare_map_used = false;
  };
  // estimate()'s steps for one view: the frame, camera and grid (checks the view); the RGBα
  // unprojection; the network's input (the LDR resized); the sky prediction of that input's
  // mirror image; the sun's flip and crop averaging into s.pred.code (sky-vector checkpoints),
  // on the sun head's distribution when there is one (sun_from_distribution).
  Single prepare_view(const InferenceView& view) const;
  Tensor unproject_view(const InferenceView& view, const Single& s) const;
  Tensor network_input(const Tensor& ldr) const;
  SkyPrediction mirror_sky(const Tensor& input);
  void average_sun(const InferenceView& view, Single& s, const SkyPrediction& mirror);
  void sun_from_distribution(const InferenceView& view, Single& s, const SkyPrediction& photo_mirror);

  std::string path_, stage_;
  int64_t step_ = 0;
  nlohmann::json config_;
  std::shared_ptr<LightingPredictor> predictor_;
  render::VsgGrid grid_template_;
  bool flip_average_ = true;
  std::vector<double> crop_scales_;
  bool visible_sun_ = true;
  data::VisibleSunParams visible_sun_params_;
  std::shared_ptr<SunGlareDetector> sun_glare_;
  double sun_glare_threshold_ = kGlareThreshold;
  double sun_glare_azimuth_weight_ = kGlareAzimuthWeight;
  double sun_glare_map_weight_ = kGlareMapWeight;
};

// The sun-strength scale that makes a fully sun-blocked ground point of this lighting as much
// darker than a lit one as the photo's own shadows are (shadow_ratio = shadowed / lit ground,
// data/sun_from_shadows.h). From the dome's irradiance on level ground, split into the sun
// (texels within sun_cone_deg of the sun direction) and the rest of the sky:
//   ratio = E_sky / (E_sky + s·E_sun)   ⇒   s = E_sky (1 − ratio) / (ratio · E_sun).
// The volume's light and the object's own occlusion of the sky are left out. ratio is clamped
// to [0.05, 0.95] and s to [1e-3, 1e4]; returns 1 when the dome has no sun or no sky above the
// horizon (nothing to calibrate).
double sun_scale_for_shadow_ratio(const EstimatedLighting& lighting, double shadow_ratio, double sun_cone_deg = 8.0);

// Lighting with its sun taken from the photo's own cast shadows (data/sun_from_shadows.h), the
// path of streetlight-insert --sun-from-shadows (single photo and batch): fit the sun on the view's
// LDR, depth and camera; when found, estimate with the fitted direction (edit's azimuth and
// elevation are replaced), then scale the sun by sun_scale_for_shadow_ratio() and estimate again,
// so the network keeps the sky's colour and the volume (a fitted direction wins over a visible
// sun, as any edit does). When not found, the estimate is estimate()'s with `edit` as given (the
// visible sun, when the estimator's cue is on and finds one, included), and intensity_scale is
// 1. Throws as estimate(); a found fit needs the "sky_decoder" sky branch.
struct ShadowSunLighting {
  EstimatedLighting lighting;
  data::ShadowSunFit fit;
  double intensity_scale = 1.0;  // applied on top of edit.intensity_scale
};
ShadowSunLighting estimate_with_shadow_sun(LightingEstimator& estimator, const InferenceView& view, SunEdit edit = {},
                                           const data::ShadowSunOptions& options = {});

// World unit direction of a panorama (azimuth, elevation) in degrees (render/equirect.h).
glm::dvec3 direction_from_azimuth_elevation_deg(double azimuth_deg, double elevation_deg);
double azimuth_deg_of(const glm::dvec3& d);
double elevation_deg_of(const glm::dvec3& d);

// Resamples a VSG volume from one canonical frame/grid onto another (nearest voxel; lobe axes
// rotated); voxels that fall outside the source grid get α = 0 and zero colour.
Tensor resample_vsg(const Tensor& vsg, const render::VsgGrid& from_grid, const CanonicalFrame& from_frame,
                    const render::VsgGrid& to_grid, const CanonicalFrame& to_frame);

}  // namespace sl::train
