// train/inference.h: frames, sun editing and multi-view fusion on a random-weight tiny model.
#include <gtest/gtest.h>

#include <omp.h>

#include <algorithm>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "nn/init.h"
#include "nn/safetensors.h"
#include "render/bvh.h"
#include "render/equirect.h"
#include "render/primitives.h"
#include "support/tool_fixture.h"
#include "train/inference.h"
#include "train/photo_insertion.h"
#include "train/street_batch.h"
#include "train/unprojection.h"
#include "util/math.h"

using sl::render::Bvh;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::Intrinsics;
using sl::render::intrinsics_from_fov;
using sl::render::make_box;
using sl::render::Mesh;
using sl::render::Placement;
using sl::render::Ray;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::VsgGrid;

namespace sl::test {

namespace {
using namespace sl::train;

InferenceView view_at(double yaw_deg) {
  const Intrinsics k = intrinsics_from_fov(1.2, 64, 32);
  InferenceView v;
  v.camera = Camera(k, rotation_from_yaw_pitch_roll(yaw_deg * kPi / 180.0, 0.0, 0.0), {0.0, 1.6, 0.0});
  v.ldr = Tensor::uniform({3, 32, 64}, 0.0, 1.0, 3);
  v.depth = ground_plane_depth(v.camera);
  return v;
}

TEST(Inference, SunEditSetsTheWorldAzimuthWhateverTheCameraYaw) {
  const std::string dir = test::tool_dir("inference_sun");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  SunEdit e;
  e.azimuth_deg = 40.0;
  e.elevation_deg = 25.0;
  for (double yaw : {0.0, 70.0, -120.0}) {
    const EstimatedLighting l = est.estimate({view_at(yaw)}, e);
    EXPECT_NEAR(azimuth_deg_of(l.sun_direction_world()), 40.0, 1e-6) << yaw;
    EXPECT_NEAR(elevation_deg_of(l.sun_direction_world()), 25.0, 1e-6) << yaw;
  }
}

TEST(Inference, FusingAViewWithItselfChangesNothing) {
  const std::string dir = test::tool_dir("inference_fuse");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  const InferenceView v = view_at(30.0);
  const EstimatedLighting one = est.estimate({v}), two = est.estimate({v, v});
  EXPECT_LT(max(abs(sub(one.env, two.env))).item(), 1e-5);
  EXPECT_NEAR(glm::length(one.sun_direction_canonical - two.sun_direction_canonical), 0.0, 1e-9);
  ASSERT_TRUE(two.vsg.defined());
  EXPECT_LT(max(abs(sub(one.vsg, two.vsg))).item(), 1e-4);
}

// Lean: the estimator builds its predictor without drawing initial values (nn::SkipInitGuard),
// since the checkpoint overwrites them all; its parameters and buffers equal the file's bit for bit.
TEST(Inference, EstimatorHoldsExactlyTheCheckpointsTensors) {
  const std::string dir = test::tool_dir("inference_lean_init");
  const std::string path = test::tiny_lighting_checkpoint(dir);
  LightingEstimator est(path);
  const nn::SafetensorsFile file = nn::read_safetensors(path);
  size_t compared = 0;
  for (const auto& [name, t] : est.predictor().state_dict()) {
    const auto it = file.tensors.find("predictor." + name);
    ASSERT_NE(it, file.tensors.end()) << name;
    EXPECT_EQ(max(abs(sub(t.to(DType::F64), it->second.to(DType::F64)))).item(), 0.0) << name;
    ++compared;
  }
  EXPECT_GT(compared, 10u);
  EXPECT_FALSE(nn::init_skipped()) << "the guard ended with the constructor";
}

// Flip averaging makes the estimate mirror-equivariant: the mirrored photo gets the mirrored sun
// and the same intensity, which a single pass of a (here random) network does not give.
// Also with crop averaging on: the centred crops of the mirror image are the mirror images of
// the photo's crops, so the averaged sun still mirrors exactly.
TEST(Inference, FlipAverageMirrorsTheSunWithThePhoto) {
  const std::string dir = test::tool_dir("inference_flip");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  EXPECT_TRUE(est.flip_average());  // the default
  EXPECT_TRUE(est.crop_scales().empty());  // off by default
  est.set_crop_scales({0.55, 0.7, 0.85});
  est.set_flip_average(false);
  const InferenceView v = view_at(0.0);
  InferenceView mirrored = v;
  mirrored.ldr = data::flip_horizontal(v.ldr);
  mirrored.depth = data::flip_horizontal(v.depth);
  auto mirror = [](const glm::dvec3& d) { return glm::dvec3(-d.x, d.y, d.z); };
  const double single_gap = glm::length(est.estimate({v}).sun_direction_canonical -
                                        mirror(est.estimate({mirrored}).sun_direction_canonical));
  EXPECT_GT(single_gap, 1e-4);
  est.set_flip_average(true);
  const EstimatedLighting a = est.estimate({v}), b = est.estimate({mirrored});
  EXPECT_LT(glm::length(a.sun_direction_canonical - mirror(b.sun_direction_canonical)), 1e-6);
  EXPECT_NEAR(glm::length(a.sun_direction_canonical), 1.0, 1e-6);
  EXPECT_LT(glm::length(a.sun_intensity_rgb - b.sun_intensity_rgb), 1e-5 * glm::length(a.sun_intensity_rgb));
}

// The fast path of estimate() (issue 52): no dome decoded per view, and the unprojection, the
// mirror image's pass, the visible-sun cue and the 3D UNet as tasks of one OpenMP team. The
// reference is the plain path it replaced, spelled out with the predictor's public calls:
// predict() on the photo and predict_sky_code() on its mirror image, averaged as inference.h
// says. Both run the same calls on the same shapes, so the network's outputs agree bit for bit:
// the volume, the latent and the averaged log intensity (the same float64 sums, rounded to
// float32) are compared exactly. The direction passes through estimate()'s rotation into the
// canonical frame and back (a dozen float64 operations on a unit vector: error below 1e-15), so
// it is compared to 1e-12, far below the 6e-8 of one float32 rounding that a different network
// output would show. (A batch of two, photo and mirror in one pass, was measured and left out:
// its outputs differ from the single passes by one float32 rounding (latent 1.5e-8, volume
// 1.2e-6 on this model) for 2 ms of CPU time on the released model.)
TEST(Inference, FastPathEqualsTheSeparatePasses) {
  const std::string dir = test::tool_dir("inference_fast_path");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  est.set_visible_sun(false);
  for (const double yaw : {0.0, 30.0}) {
    const InferenceView v = view_at(yaw);
    const EstimatedLighting fast = est.estimate({v});

    NoGradGuard no_grad;
    LightingPredictor& net = est.predictor();
    const LightingPredictorOptions& po = net.options();
    const Tensor image = unsqueeze(resize_bilinear(v.ldr, po.image_height, po.image_width), 0);
    const Tensor rgba = unsqueeze(unproject_rgba(v.ldr, v.depth, fast.camera, fast.grid), 0);
    const LightingPrediction p = net.predict(image, rgba);
    const SkyCode m = net.predict_sky_code(unsqueeze(data::flip_horizontal(select(image, 0, 0).contiguous()), 0));

    ASSERT_TRUE(fast.vsg.defined());
    EXPECT_EQ(max(abs(sub(fast.vsg, select(p.vsg, 0, 0)))).item(), 0.0);
    EXPECT_EQ(max(abs(sub(fast.sky_code.latent, p.code.latent))).item(), 0.0);
    const std::vector<double> li = p.code.log_intensity.to_vector(), mli = m.log_intensity.to_vector();
    std::vector<double> avg(3);
    for (int c = 0; c < 3; ++c) avg[c] = 0.5 * (li[c] + mli[c]);
    EXPECT_EQ(max(abs(sub(fast.sky_code.log_intensity, Tensor::from_vector(avg, {1, 3})))).item(), 0.0);
    const std::vector<double> d = p.code.dir.to_vector(), md = m.dir.to_vector();
    const glm::dvec3 own(d[0], d[1], d[2]), mirrored(-md[0], md[1], md[2]);
    const glm::dvec3 e = glm::normalize(own + mirrored);  // stored as float32, then normalised again
    const glm::dvec3 expect = glm::normalize(glm::dvec3(float(e.x), float(e.y), float(e.z)));
    EXPECT_LT(glm::length(fast.sun_direction_canonical - expect), 1e-12);
    EXPECT_NEAR(fast.sun_flip_spread_deg, std::atan2(glm::length(glm::cross(own, mirrored)), glm::dot(own, mirrored)) * 180.0 / kPi,
                1e-12);
  }
}

// The estimate is the same bits on one thread and on two (its parts run as tasks; which thread
// runs which part changes nothing), with the visible-sun cue, flip averaging and two views.
TEST(Inference, EstimateIsTheSameOnOneAndTwoThreads) {
  const std::string dir = test::tool_dir("inference_threads");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  const std::vector<InferenceView> views{view_at(0.0), view_at(40.0)};
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const EstimatedLighting one = est.estimate(views);
  omp_set_num_threads(2);
  const EstimatedLighting two = est.estimate(views);
  omp_set_num_threads(threads);
  EXPECT_EQ(max(abs(sub(one.env, two.env))).item(), 0.0);
  EXPECT_EQ(max(abs(sub(one.vsg, two.vsg))).item(), 0.0);
  EXPECT_EQ(one.sun_direction_canonical, two.sun_direction_canonical);
  EXPECT_EQ(one.sun_flip_spread_deg, two.sun_flip_spread_deg);
}

// A tiny checkpoint with a sun head over a 4 × 16 grid (model.sun_grid), and its config.
nlohmann::json sun_head_config() {
  nlohmann::json c = tiny_lighting_config();
  c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  return c;
}
std::string sun_head_checkpoint(const std::string& dir, const nlohmann::json& c) {
  const std::string path = dir + "/sun_head.safetensors";
  auto predictor = std::make_shared<LightingPredictor>(predictor_options(c));
  nn::Module holder("LightingModel");
  holder.register_module("predictor", predictor);
  nn::save_checkpoint(path, holder, nullptr, nn::CheckpointInfo{.stage = "lighting", .step = 1, .config_json = c.dump()});
  return path;
}

// The sun head's distribution for a view by hand, from the predictor's own passes: the photo's,
// averaged with the mirrored photo's (mirrored back) when `flip`.
std::vector<double> sun_head_probabilities(LightingEstimator& est, const nlohmann::json& c, const InferenceView& v, bool flip) {
  NoGradGuard ng;
  const SunGrid grid{c["model"]["sun_grid"]["elevation_bins"].get<int64_t>(), c["model"]["sun_grid"]["azimuth_bins"].get<int64_t>()};
  const Tensor image = unsqueeze(resize_bilinear(v.ldr, c["model"]["image_height"].get<int64_t>(),
                                                 c["model"]["image_width"].get<int64_t>()),
                                 0);
  std::vector<double> p = softmax_row(select(est.predictor().predict_sky(image).sun_logits, 0, 0).to_vector());
  if (!flip) return p;
  const std::vector<double> m = mirror_cells(
      grid, softmax_row(select(est.predictor().predict_sky(unsqueeze(data::flip_horizontal(select(image, 0, 0).contiguous()), 0))
                                   .sun_logits,
                               0, 0)
                            .to_vector()));
  for (size_t k = 0; k < p.size(); ++k) p[k] = 0.5 * (p[k] + m[k]);
  return p;
}

// The confidence of an estimate is the angle between the sun of the photo's pass and the mirror
// image of the mirrored photo's pass: what the two single passes give, the same for the photo and
// its mirror image, the larger of two views', and not measured without flip averaging.
// A checkpoint with a sun head (model.sun_grid, issue 53): the estimate's sun is the mode of the
// distribution averaged over the photo's pass and its mirrored pass (mirrored back), not the sky
// head's direction; its confidence is the probability near that mode; the mirror image of the
// photo gets the mirror image of the sun.
TEST(Inference, ASunHeadsModeIsTheSunAndItsMassTheConfidence) {
  const std::string dir = test::tool_dir("inference_sun_head");
  const nlohmann::json c = sun_head_config();
  const std::string path = sun_head_checkpoint(dir, c);
  LightingEstimator est(path);
  est.set_visible_sun(false);
  const InferenceView v = view_at(0.0);
  const SunGrid grid{4, 16};
  for (const bool flip : {false, true}) {
    est.set_flip_average(flip);
    const EstimatedLighting l = est.estimate({v});
    // The same readout by hand, from the predictor's own passes.
    const SunReadout r = read_sun_distribution(grid, sun_head_probabilities(est, c, v, flip));
    EXPECT_LT(glm::length(l.sun_direction_canonical - r.direction), 1e-5) << "flip " << flip;
    EXPECT_NEAR(l.sun_probability, r.confidence, 1e-9);
    EXPECT_GT(l.sun_probability, 0.0);
    EXPECT_LE(l.sun_probability, 1.0);
  }
  // Flip averaging makes the sun of the mirror image the mirror image of the sun.
  est.set_flip_average(true);
  InferenceView mirrored = v;
  mirrored.ldr = data::flip_horizontal(v.ldr);
  mirrored.depth = data::flip_horizontal(v.depth);
  const glm::dvec3 a = est.estimate({v}).sun_direction_canonical, b = est.estimate({mirrored}).sun_direction_canonical;
  EXPECT_LT(glm::length(a - glm::dvec3(-b.x, b.y, b.z)), 1e-5);
  // A checkpoint without a sun head reports no probability.
  LightingEstimator plain(test::tiny_lighting_checkpoint(dir));
  EXPECT_TRUE(std::isnan(plain.estimate({v}).sun_probability));
}

TEST(Inference, FlipSpreadIsTheAngleBetweenAPassAndItsMirroredPass) {
  const std::string dir = test::tool_dir("inference_spread");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  const InferenceView v = view_at(0.0);
  InferenceView mirrored = v;
  mirrored.ldr = data::flip_horizontal(v.ldr);
  mirrored.depth = data::flip_horizontal(v.depth);
  est.set_flip_average(false);
  const EstimatedLighting one = est.estimate({v}), other = est.estimate({mirrored});
  EXPECT_TRUE(std::isnan(one.sun_flip_spread_deg));
  const glm::dvec3 a = one.sun_direction_canonical, b = other.sun_direction_canonical;
  const glm::dvec3 mb(-b.x, b.y, b.z);
  const double expect = std::atan2(glm::length(glm::cross(a, mb)), glm::dot(a, mb)) * 180.0 / kPi;
  ASSERT_GT(expect, 1e-3);  // a random network does not agree with its mirror image
  est.set_flip_average(true);
  const EstimatedLighting l = est.estimate({v}), lm = est.estimate({mirrored});
  EXPECT_NEAR(l.sun_flip_spread_deg, expect, 1e-3);
  EXPECT_NEAR(lm.sun_flip_spread_deg, expect, 1e-3);
  InferenceView turned = view_at(0.0);
  turned.ldr = Tensor::uniform({3, 32, 64}, 0.0, 1.0, 11);
  const double s2 = est.estimate({turned}).sun_flip_spread_deg;
  EXPECT_NEAR(est.estimate({v, turned}).sun_flip_spread_deg, std::max(expect, s2), 1e-9);
}

// Crop averaging (issue 39): the view's sun and each centred crop's vote with unit weight; the
// crop spread is the largest angle between the photo's sun and a crop's. Reproduced here from
// single passes: the crop at scale 0.5 of a 64 × 32 photo is its pixels [8, 24) × [16, 48) (equal
// margins), estimated as a photo of its own.
TEST(Inference, CropAveragingAveragesThePhotosSunWithItsCentredCrops) {
  const std::string dir = test::tool_dir("inference_crops");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  est.set_flip_average(false);
  est.set_crop_scales({});
  const InferenceView v = view_at(0.0);
  const EstimatedLighting photo = est.estimate({v});
  EXPECT_TRUE(std::isnan(photo.sun_crop_spread_deg));  // not measured when off
  InferenceView crop = v;
  crop.ldr = slice(slice(v.ldr, 1, 8, 24), 2, 16, 48).contiguous();
  crop.camera = Camera(intrinsics_from_fov(1.2, 32, 16), v.camera.rotation(), v.camera.position());
  crop.depth = ground_plane_depth(crop.camera);
  const glm::dvec3 p = glm::normalize(photo.sun_direction_canonical),
                   c = glm::normalize(est.estimate({crop}).sun_direction_canonical);
  const double expect = std::atan2(glm::length(glm::cross(p, c)), glm::dot(p, c)) * 180.0 / kPi;
  ASSERT_GT(expect, 1e-3);  // a random network's crop disagrees with the photo
  est.set_crop_scales({0.5});
  const EstimatedLighting averaged = est.estimate({v});
  EXPECT_NEAR(averaged.sun_crop_spread_deg, expect, 1e-3);
  EXPECT_LT(glm::length(averaged.sun_direction_canonical - glm::normalize(p + c)), 1e-5);
  // The sun's intensity and the sky latent stay the photo's own.
  EXPECT_EQ(averaged.sky_code.log_intensity.to_vector(), photo.sky_code.log_intensity.to_vector());
  EXPECT_EQ(averaged.sky_code.latent.to_vector(), photo.sky_code.latent.to_vector());
}

// A photo whose every centred crop looks the same (one colour) gets the photo's own sun and a
// crop spread of 0: crop averaging adds agreement, not a bias.
TEST(Inference, CropAveragingOfAUniformPhotoChangesNothing) {
  const std::string dir = test::tool_dir("inference_crops_uniform");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  InferenceView v = view_at(0.0);
  v.ldr = Tensor::full({3, 32, 64}, 0.4, DType::F32);
  est.set_crop_scales({});
  const EstimatedLighting off = est.estimate({v});
  est.set_crop_scales({0.55, 0.7, 0.85});
  const EstimatedLighting on = est.estimate({v});
  EXPECT_LT(glm::length(on.sun_direction_canonical - off.sun_direction_canonical), 1e-6);
  EXPECT_LT(on.sun_crop_spread_deg, 1e-3);
}

TEST(Inference, CropScalesOutsideTheOpenUnitIntervalAreRefused) {
  const std::string dir = test::tool_dir("inference_crops_bad");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  for (const double bad : {0.0, 1.0, -0.5, 1.5, std::nan("")}) {
    try {
      est.set_crop_scales({0.7, bad});
      ADD_FAILURE() << "accepted scale " << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("crop scale"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(est.crop_scales().empty());  // a refused list leaves the setting as it was
}

// A street view (blue sky over grey ground) with, optionally, a clipped sun disk of radius 2.5 px
// whose glare fades over 3 px at continuous pixel (u, v): what data/visible_sun.h finds.
InferenceView sunny_view(double yaw_deg, bool with_sun, double u = 44.3, double v = 8.6) {
  InferenceView view = view_at(yaw_deg);
  const int h = 32, w = 64;
  std::vector<float> px(3 * h * w);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const bool sky = r < 18;
      const float rgb[3] = {sky ? 0.5f : 0.35f, sky ? 0.62f : 0.35f, sky ? 0.85f : 0.33f};
      const double d = std::hypot(c + 0.5 - u, r + 0.5 - v);
      const double white = !with_sun ? 0.0 : d <= 2.5 ? 1.0 : std::exp(-(d - 2.5) / 3.0);
      for (int ch = 0; ch < 3; ++ch) px[(ch * h + r) * w + c] = static_cast<float>(white + (1.0 - white) * rgb[ch]);
    }
  view.ldr = Tensor::from_vector(std::vector<double>(px.begin(), px.end()), {3, h, w}).to(DType::F32);
  return view;
}

// Issue 39 item 3: a sun the photo shows is where the sun is, whatever the network guessed; the
// direction goes through the SunEdit path (decoded into the dome), the spread becomes 0.
TEST(Inference, VisibleSunSetsTheSunToTheRayThroughIt) {
  const std::string dir = test::tool_dir("inference_visible_sun");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  EXPECT_TRUE(est.visible_sun());  // the default
  const InferenceView v = sunny_view(30.0, true);
  const EstimatedLighting on = est.estimate({v});
  est.set_visible_sun(false);
  const EstimatedLighting off = est.estimate({v});
  ASSERT_TRUE(on.visible_sun_found);
  EXPECT_FALSE(off.visible_sun_found);
  EXPECT_EQ(on.visible_sun_view, 0);
  EXPECT_NEAR(on.visible_sun_pixel.x, 44.3, 0.3);
  EXPECT_NEAR(on.visible_sun_pixel.y, 8.6, 0.3);
  EXPECT_GT(on.visible_sun_score, 0.0);
  const glm::dvec3 ray = v.camera.ray(on.visible_sun_pixel.x, on.visible_sun_pixel.y).direction;
  EXPECT_LT(glm::length(on.sun_direction_world() - ray), 1e-9);
  EXPECT_GT(glm::length(off.sun_direction_world() - ray), 1e-3);  // a random network looks elsewhere
  // The decoder saw the new direction: the dome moved.
  EXPECT_GT(max(abs(sub(on.env, off.env))).item(), 1e-4);
  EXPECT_EQ(on.sun_flip_spread_deg, 0.0);
  EXPECT_EQ(on.network_sun_flip_spread_deg, off.sun_flip_spread_deg);
  EXPECT_GT(off.sun_flip_spread_deg, 0.0);
  // The hedge (the network's sun height) is 0 when the photo showed the sun, as the spread is.
  EXPECT_EQ(on.sun_hedge, 0.0);
  EXPECT_EQ(off.sun_hedge, std::clamp(off.sun_direction_canonical.y, 0.0, 1.0));
}

TEST(Inference, WithoutAVisibleSunTheCueChangesNothing) {
  const std::string dir = test::tool_dir("inference_no_visible_sun");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  for (const InferenceView& v : {sunny_view(-40.0, false), view_at(10.0)}) {
    const EstimatedLighting on = est.estimate({v});
    est.set_visible_sun(false);
    const EstimatedLighting off = est.estimate({v});
    est.set_visible_sun(true);
    EXPECT_FALSE(on.visible_sun_found);
    EXPECT_EQ(on.visible_sun_view, -1);
    EXPECT_EQ(max(abs(sub(on.env, off.env))).item(), 0.0);
    EXPECT_EQ(max(abs(sub(on.vsg, off.vsg))).item(), 0.0);
    EXPECT_EQ(on.sun_direction_canonical, off.sun_direction_canonical);
    EXPECT_EQ(on.sun_intensity_rgb, off.sun_intensity_rgb);
    EXPECT_EQ(on.sun_flip_spread_deg, off.sun_flip_spread_deg);
  }
}

// A glare detector whose every weight is 0 and whose "no sun" bias is b: every cell has the same
// probability and p_sun = 512 / (512 + e^b), so for b = −50 it always fires and for b = +50 never.
// With azimuth_bins > 0 it also has an azimuth head whose logits are `azimuth_bias` (0 elsewhere).
std::shared_ptr<SunGlareDetector> constant_glare(double none_bias, int64_t azimuth_bins = 0,
                                                 const std::vector<double>& azimuth_bias = {}) {
  auto net = std::make_shared<SunGlareDetector>(SunGlareOptions{.width = 2, .azimuth_bins = azimuth_bins, .seed = 1});
  NoGradGuard ng;
  for (auto& [name, t] : net->named_parameters()) {
    float* p = t.data<float>();
    for (int64_t i = 0; i < t.numel(); ++i)
      p[i] = name == "none.bias" ? float(none_bias)
             : name == "azimuth.2.bias" && size_t(i) < azimuth_bias.size() ? float(azimuth_bias[size_t(i)])
                                                                           : 0.0f;
  }
  return net;
}

TEST(Inference, TheLearnedGlareDetectorFillsInWhereTheDiskTestFindsNothing) {
  const std::string dir = test::tool_dir("inference_sun_glare");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  const InferenceView no_disk = view_at(10.0), disk = sunny_view(30.0, true);
  const EstimatedLighting plain = est.estimate({no_disk}), plain_disk = est.estimate({disk});
  ASSERT_FALSE(plain.visible_sun_found);
  ASSERT_TRUE(plain_disk.visible_sun_found);
  // A detector that never fires changes nothing.
  est.set_sun_glare(constant_glare(50.0));
  const EstimatedLighting quiet = est.estimate({no_disk});
  EXPECT_FALSE(quiet.visible_sun_found);
  EXPECT_EQ(max(abs(sub(quiet.env, plain.env))).item(), 0.0);
  EXPECT_EQ(quiet.sun_direction_canonical, plain.sun_direction_canonical);
  // One that always fires sets the sun to the ray through its pixel, where the disk test found none.
  est.set_sun_glare(constant_glare(-50.0));
  const EstimatedLighting fired = est.estimate({no_disk});
  ASSERT_TRUE(fired.visible_sun_found);
  EXPECT_TRUE(fired.visible_sun_learned);
  EXPECT_EQ(fired.visible_sun_view, 0);
  EXPECT_NEAR(fired.visible_sun_score, 1.0, 1e-12);
  const render::Intrinsics& in = no_disk.camera.intrinsics();
  const GlareReading r = read_glare(Tensor::from_vector(std::vector<double>(kGlareOutputs, 0.0), {kGlareOutputs}),
                                    in.height, in.width);
  EXPECT_NEAR(fired.visible_sun_pixel.x, r.pixel.x, 1e-9);
  EXPECT_NEAR(fired.visible_sun_pixel.y, r.pixel.y, 1e-9);
  const glm::dvec3 ray = no_disk.camera.ray(r.pixel.x, r.pixel.y).direction;
  EXPECT_LT(glm::length(fired.sun_direction_world() - ray), 1e-9);
  EXPECT_EQ(fired.sun_flip_spread_deg, 0.0);  // measured in the photo, as for a disk
  EXPECT_EQ(fired.sun_hedge, 0.0);
  // The disk test still wins where it finds a disk: the same estimate as without a detector.
  const EstimatedLighting with_disk = est.estimate({disk});
  EXPECT_FALSE(with_disk.visible_sun_learned);
  EXPECT_EQ(with_disk.visible_sun_pixel, plain_disk.visible_sun_pixel);
  EXPECT_EQ(max(abs(sub(with_disk.env, plain_disk.env))).item(), 0.0);
  // Off with the cue; thresholds outside (0, 1] are refused.
  est.set_visible_sun(false);
  EXPECT_FALSE(est.estimate({no_disk}).visible_sun_found);
  EXPECT_THROW(est.set_sun_glare(constant_glare(0.0), 0.0), Error);
  EXPECT_THROW(est.set_sun_glare(constant_glare(0.0), 1.5), Error);
}

// A detector with an azimuth head reweighs the sun head's distribution (train/sun_distribution.h
// weigh_by_azimuth) before its mode is read, whether or not it fires; at weight 0 the estimate is
// the same bits as without a detector.
TEST(Inference, TheGlareDetectorsAzimuthHeadReweighsTheSunHead) {
  const std::string dir = test::tool_dir("inference_glare_azimuth");
  const nlohmann::json c = sun_head_config();
  const std::string path = sun_head_checkpoint(dir, c);
  LightingEstimator est(path);
  const InferenceView v = view_at(0.0);
  const EstimatedLighting plain = est.estimate({v});
  ASSERT_FALSE(plain.visible_sun_found);
  EXPECT_FALSE(plain.glare_azimuth_used);
  // An azimuth head sure the sun is behind the camera: sectors 0 and 7 of 8 (|azimuth| > 135°),
  // symmetric, so that the flip-averaged reading is the head's own softmax.
  const std::vector<double> behind = {8.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 8.0};
  est.set_sun_glare(constant_glare(50.0, 8, behind), kGlareThreshold, 1.0);
  const EstimatedLighting reweighed = est.estimate({v});
  EXPECT_FALSE(reweighed.visible_sun_found);
  EXPECT_TRUE(reweighed.glare_azimuth_used);
  EXPECT_GT(std::abs(azimuth_deg_of(reweighed.sun_direction_canonical)), 135.0);
  // The same readout by hand: the flip-averaged sun head's distribution reweighed by the softmax.
  {
    const SunGrid grid{4, 16};
    const SunReadout r =
        read_sun_distribution(grid, weigh_by_azimuth(grid, sun_head_probabilities(est, c, v, true), softmax_row(behind), 1.0));
    EXPECT_LT(glm::length(reweighed.sun_direction_canonical - r.direction), 1e-5);
    EXPECT_NEAR(reweighed.sun_probability, r.confidence, 1e-9);
  }
  // Weight 0: the same bits as without a detector.
  est.set_sun_glare(constant_glare(50.0, 8, behind), kGlareThreshold, 0.0);
  const EstimatedLighting off = est.estimate({v});
  EXPECT_FALSE(off.glare_azimuth_used);
  EXPECT_EQ(off.sun_direction_canonical, plain.sun_direction_canonical);
  EXPECT_EQ(max(abs(sub(off.env, plain.env))).item(), 0.0);
  EXPECT_EQ(off.sun_probability, plain.sun_probability);
  EXPECT_THROW(est.set_sun_glare(constant_glare(50.0, 8, behind), kGlareThreshold, -1.0), Error);
  EXPECT_THROW(est.set_sun_glare(constant_glare(50.0, 8, behind), kGlareThreshold, std::nan("")), Error);
}

// Below the threshold, the glare map (train/sun_glare.h glare_sky_factor) reweighs the sun head's
// distribution when its weight is > 0: the same readout as by hand; weight 0 gives the bits of no
// detector. The constant detector's map is flat over the image (every cell's logit 0), so its
// mirror image is itself.
TEST(Inference, TheGlareMapReweighsTheSunHeadBelowTheThreshold) {
  const std::string dir = test::tool_dir("inference_glare_map");
  const nlohmann::json c = sun_head_config();
  LightingEstimator est(sun_head_checkpoint(dir, c));
  const InferenceView v = view_at(0.0);
  const EstimatedLighting plain = est.estimate({v});
  ASSERT_FALSE(plain.visible_sun_found);
  // none logit ln 512: p_sun = 0.5, below the threshold; each cell 0.5 / 512.
  const double none = std::log(512.0);
  est.set_sun_glare(constant_glare(none), kGlareThreshold, 0.0, 1.0);
  const EstimatedLighting l = est.estimate({v});
  EXPECT_FALSE(l.visible_sun_found);
  EXPECT_TRUE(l.glare_map_used);
  EXPECT_FALSE(l.glare_azimuth_used);
  {
    const SunGrid grid{4, 16};
    std::vector<double> logits(kGlareOutputs, 0.0);
    logits[0] = none;
    const render::Intrinsics& in = v.camera.intrinsics();
    const GlareReading g = read_glare(Tensor::from_vector(logits, {kGlareOutputs}), in.height, in.width);
    const Camera canonical = canonical_frame(v.camera).camera(v.camera);
    const std::vector<double> f = glare_sky_factor(grid, canonical, g.cells);
    const SunReadout r = read_sun_distribution(grid, weigh_by_cells(grid, sun_head_probabilities(est, c, v, true), f, 1.0));
    EXPECT_LT(glm::length(l.sun_direction_canonical - r.direction), 1e-5);
    EXPECT_NEAR(l.sun_probability, r.confidence, 1e-9);
    // The flat map raises the cells in view (0.5 / 512 per cell against the prior's 0.281 / 512).
    EXPECT_NEAR(*std::max_element(f.begin(), f.end()), kGlareNoSunPrior / (1.0 - kGlareNoSunPrior), 1e-6);  // float32 logits
  }
  est.set_sun_glare(constant_glare(none), kGlareThreshold, 0.0, 0.0);
  const EstimatedLighting off = est.estimate({v});
  EXPECT_FALSE(off.glare_map_used);
  EXPECT_EQ(off.sun_direction_canonical, plain.sun_direction_canonical);
  EXPECT_EQ(max(abs(sub(off.env, plain.env))).item(), 0.0);
  EXPECT_EQ(off.sun_probability, plain.sun_probability);
  EXPECT_THROW(est.set_sun_glare(constant_glare(none), kGlareThreshold, 0.0, -1.0), Error);
  EXPECT_THROW(est.set_sun_glare(constant_glare(none), kGlareThreshold, 0.0, std::nan("")), Error);
}

TEST(Inference, AnExplicitSunEditWinsOverTheVisibleSun) {
  const std::string dir = test::tool_dir("inference_visible_sun_edit");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  const InferenceView v = sunny_view(-25.0, true);
  SunEdit e;
  e.azimuth_deg = 40.0;
  e.elevation_deg = 25.0;
  const EstimatedLighting edited = est.estimate({v}, e);
  EXPECT_TRUE(edited.visible_sun_found);
  EXPECT_NEAR(azimuth_deg_of(edited.sun_direction_world()), 40.0, 1e-6);
  EXPECT_NEAR(elevation_deg_of(edited.sun_direction_world()), 25.0, 1e-6);
  est.set_visible_sun(false);
  const EstimatedLighting edited_off = est.estimate({v}, e);
  EXPECT_EQ(max(abs(sub(edited.env, edited_off.env))).item(), 0.0);
  EXPECT_EQ(edited.sun_flip_spread_deg, edited_off.sun_flip_spread_deg);  // the network's, as for any edit
  EXPECT_EQ(edited.sun_hedge, edited_off.sun_hedge);
  EXPECT_EQ(edited.sun_hedge, est.estimate({v}).sun_hedge);  // the cue is off here: the network's own
  // Field by field: an edit of the elevation alone keeps the visible sun's azimuth.
  est.set_visible_sun(true);
  const EstimatedLighting found = est.estimate({v});
  SunEdit el;
  el.elevation_deg = 60.0;
  const EstimatedLighting partly = est.estimate({v}, el);
  EXPECT_NEAR(azimuth_deg_of(partly.sun_direction_world()), azimuth_deg_of(found.sun_direction_world()), 1e-6);
  EXPECT_NEAR(elevation_deg_of(partly.sun_direction_world()), 60.0, 1e-6);
}

TEST(Inference, ResamplingOntoTheSameGridIsTheIdentity) {
  VsgGrid g;
  g.dims = {8, 8, 4};
  CanonicalFrame f;
  const Tensor vsg = Tensor::uniform({8, 8, 8, 4}, 0.0, 1.0, 5);
  EXPECT_LT(max(abs(sub(resample_vsg(vsg, g, f, g, f), vsg))).item(), 1e-6);
}

TEST(Inference, GroundPlaneDepthPutsBelowHorizonPixelsOnYZero) {
  const Camera cam = view_at(0.0).camera;
  const Tensor d = ground_plane_depth(cam);
  const float* p = d.data<float>();
  for (int r = 20; r < 32; r += 5) {
    const double z = p[r * 64 + 10];
    ASSERT_GT(z, 0.0);
    EXPECT_NEAR(cam.unproject(10.5, r + 0.5, z).y, 0.0, 1e-4);
  }
  EXPECT_EQ(p[2 * 64 + 10], 0.0f);  // above the horizon: a hole
}

// The object a photo insertion renders (in the lighting's canonical frame) is the object the
// pose describes in the world (the frame of the generator's truth and of the KITTI labels),
// whatever the camera's yaw: its coverage matches a world-frame ray cast of the posed mesh.
TEST(Inference, InsertedObjectMatchesTheWorldPoseWhateverTheCameraYaw) {
  const std::string dir = test::tool_dir("inference_pose");
  LightingEstimator est(test::tiny_lighting_checkpoint(dir));
  const Mesh car = make_box({-2.25f, 0.0f, -0.9f}, {2.25f, 1.5f, 0.9f});  // object frame: long along +X
  for (double cam_yaw : {0.0, 35.0, -50.0}) {
    const InferenceView v = view_at(cam_yaw);
    const EstimatedLighting l = est.estimate({v});
    // 8 m in front of the camera, heading 30° off the camera's own heading.
    Placement pose;
    pose.x_m = 8.0 * v.camera.rotation()[2].x;
    pose.z_m = 8.0 * v.camera.rotation()[2].z;
    pose.yaw_deg = 30.0;
    PhotoInsertionOptions o;
    o.aa_samples = 4, o.light_samples = 1, o.shadow_rays = 1, o.shadow_width = 8, o.shadow_height = 4;
    const PhotoInsertion ins = insert_into_photo(l, v.ldr, v.depth, v.camera, car, pose, o);
    // World frame: yaw about +Y (+X turns toward −Z), then translate; ray cast per pixel centre.
    const double y = pose.yaw_deg * kPi / 180.0, c = std::cos(y), s = std::sin(y);
    Mesh world = car;
    for (glm::vec3& p : world.positions)
      p = glm::vec3(float(c * p.x + s * p.z + pose.x_m), p.y, float(-s * p.x + c * p.z + pose.z_m));
    const Bvh bvh(world);
    const int W = v.camera.intrinsics().width, H = v.camera.intrinsics().height;
    int both = 0, either = 0;
    for (int r = 0; r < H; ++r)
      for (int col = 0; col < W; ++col) {
        const CameraRay cr = v.camera.pixel_ray(col + 0.5, r + 0.5);
        Ray ray;
        ray.origin = glm::vec3(cr.origin);
        ray.direction = glm::vec3(cr.direction);
        const bool truth = bvh.intersect(ray).hit();
        const bool ours = ins.object_mask.data<float>()[r * W + col] >= 0.5f;
        both += truth && ours;
        either += truth || ours;
      }
    ASSERT_GT(either, 20) << "camera yaw " << cam_yaw;
    EXPECT_GT(double(both) / either, 0.9) << "camera yaw " << cam_yaw << ": IoU of the rendered and the posed object";
  }
}

// A dome of uniform sky radiance 1 with one bright texel at the sun: the scale makes the sun's
// ground irradiance s·E_sun equal E_sky (1 − r) / r, so it is inversely proportional to the sun's
// brightness and falls as the photo's shadows get lighter.
TEST(Inference, SunScaleForShadowRatioMatchesThePhotosShadowDarkness) {
  const auto dome = [](float sun) {
    EstimatedLighting l;
    l.env = Tensor::full({3, 16, 64}, 1.0f);
    float* e = l.env.data<float>();
    const int row = 4, col = 40;  // elevation 45° - 5.6°·0.5, some azimuth
    for (int c = 0; c < 3; ++c) e[c * 16 * 64 + row * 64 + col] = sun;
    const render::equirect::Dir d = render::equirect::uv_to_direction(col + 0.5, row + 0.5, 64, 16);
    l.sun_direction_canonical = {d.x, d.y, d.z};
    return l;
  };
  const double s1 = sun_scale_for_shadow_ratio(dome(1000.0f), 0.25);
  const double s2 = sun_scale_for_shadow_ratio(dome(2000.0f), 0.25);
  EXPECT_GT(s1, 0.0);
  EXPECT_NEAR(s2 / s1, 0.5, 0.01);  // the sun texel dominates its cone
  EXPECT_LT(sun_scale_for_shadow_ratio(dome(1000.0f), 0.5), s1);
  // r = 0.5 means s·E_sun = E_sky: with E_sky ≈ π·1 (the cone's few texels aside) and the sun's
  // irradiance = (1000 − 1)·sin(elevation)·Ω_texel.
  const double omega = render::equirect::pixel_solid_angle(4, 64, 16);
  const double el = (0.5 - 4.5 / 16.0) * kPi;
  const double e_sun = 1000.0 * std::sin(el) * omega;  // the texel, plus its sky within the cone
  EXPECT_NEAR(sun_scale_for_shadow_ratio(dome(1000.0f), 0.5) * e_sun / kPi, 1.0, 0.1);
  // No sky above the horizon, or no sun: nothing to calibrate.
  EstimatedLighting dark = dome(1000.0f);
  dark.env = Tensor::zeros({3, 16, 64});
  EXPECT_EQ(sun_scale_for_shadow_ratio(dark, 0.3), 1.0);
  EXPECT_THROW(sun_scale_for_shadow_ratio(dome(10.0f), std::nan("")), Error);
}

}  // namespace

}  // namespace sl::test
