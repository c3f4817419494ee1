// train/lighting_refinement.h: discriminator test-time optimisation (Fig. 7) on a tiny model,
// with discriminators whose score is a known function of the composite: all weights positive
// and no norm, so on an LDR input (≥ 0) every LeakyReLU is the identity and D is a positive
// (or, with the last layer negated, negative) weighted sum of the composite's pixels.
#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "nn/checkpoint.h"
#include "render/primitives.h"
#include "support/tool_fixture.h"
#include "train/inference.h"
#include "train/lighting_refinement.h"
#include "train/photo_insertion.h"
#include "util/math.h"

using sl::render::Camera;
using sl::render::InsertionInputs;
using sl::render::Intrinsics;
using sl::render::intrinsics_from_fov;
using sl::render::make_box;
using sl::render::Mesh;
using sl::render::Placement;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::test {

namespace {
using namespace sl::train;

// D = sign · (positive weighted sum of the LDR composite): sign +1 prefers a brighter image.
std::shared_ptr<nn::PatchDiscriminator> linear_discriminator(double sign) {
  auto d = std::make_shared<nn::PatchDiscriminator>(
      nn::PatchDiscriminatorOptions{.base_channels = 2, .layers = 1, .norm = "none"});
  const nn::NamedTensors params = d->named_parameters();
  std::string last_weight;
  for (const auto& [name, t] : params)
    if (name.size() > 6 && name.substr(name.size() - 6) == "weight") last_weight = name;
  for (const auto& [name, t] : params) {
    Tensor p = t;
    if (name.substr(name.size() - 4) == "bias") p.fill_(0.0);
    else p.fill_(name == last_weight ? sign * 0.05 : 0.05);
  }
  return d;
}

struct Scene {
  std::string dir;
  std::unique_ptr<LightingEstimator> est;
  InferenceView view;
  Mesh object = make_box({-2.25f, 0.0f, -0.9f}, {2.25f, 1.5f, 0.9f});
  Placement pose;
  PhotoInsertionOptions insertion;

  // analytic_sky: the decoder's weights zeroed, so its network adds a constant sky of radiance 1
  // and the sky is that plus the decoder's analytic sun lobe (train/sky_autoencoder.h): the sun
  // vector then moves only the sun, not a random network's sky.
  // Its dome is then 16×64 with a sun lobe 3 texels wide, so the lobe's energy on the grid barely
  // depends on where the sun sits between texel centres (a one-texel lobe on the tiny model's
  // 8×32 dome gains or loses energy as it moves, which the direction's gradient follows).
  explicit Scene(const std::string& name, bool analytic_sky = false) : dir(tool_dir(name)) {
    nlohmann::json c = tiny_lighting_config();
    if (analytic_sky) {
      c["model"]["sky"]["height"] = 16;
      c["model"]["sky"]["width"] = 64;
      c["model"]["sky"]["sun_lobe_texels"] = 3.0;
    }
    nn::Module holder("LightingModel");
    holder.register_module("predictor", std::make_shared<LightingPredictor>(predictor_options(c)));
    const std::string path = dir + "/lighting.safetensors";
    nn::save_checkpoint(path, holder, nullptr, nn::CheckpointInfo{.stage = "lighting", .step = 1, .config_json = c.dump()});
    est = std::make_unique<LightingEstimator>(path);
    if (analytic_sky)
      for (const auto& [n, t] : est->predictor().sky_decoder()->named_parameters()) Tensor(t).fill_(0.0);
    const Intrinsics k = intrinsics_from_fov(1.2, 64, 32);
    view.camera = Camera(k, rotation_from_yaw_pitch_roll(0.0, 0.0, 0.0), {0.0, 1.6, 0.0});
    view.ldr = Tensor::full({3, 32, 64}, 0.4);
    view.depth = ground_plane_depth(view.camera);
    pose.x_m = 0.0;
    pose.z_m = -8.0;  // 8 m ahead of a camera looking down −Z
    pose.yaw_deg = 0.0;
    insertion.aa_samples = 2;
    insertion.light_samples = 16;
    insertion.shadow_width = 32;
    insertion.shadow_height = 16;
    insertion.shadow_rays = 32;
    insertion.volume_query = est->volume_query();
  }
  // The estimate with its sun set to (azimuth, elevation) in degrees and scaled by `intensity`;
  // without the volume unless asked (a random volume hides the sky).
  EstimatedLighting lighting(double azimuth, double elevation, double intensity, bool volume = false) {
    SunEdit e;
    e.azimuth_deg = azimuth;
    e.elevation_deg = elevation;
    e.intensity_scale = intensity;
    EstimatedLighting l = est->estimate({view}, e);
    if (!volume) l.vsg = Tensor();
    return l;
  }
  InsertionInputs inputs(const EstimatedLighting& l) const {
    return photo_insertion_inputs(l, view.ldr, view.depth, view.camera, object, pose, insertion);
  }
  RefinementResult refine(const EstimatedLighting& l, nn::PatchDiscriminator& d, const RefinementOptions& r) {
    return refine_lighting(l, *est->predictor().sky_decoder(), d, inputs(l), insertion, r);
  }
};

bool finite(const Tensor& t) {
  for (double v : t.detach().to_vector())
    if (!std::isfinite(v)) return false;
  return true;
}

TEST(LightingRefinement, AreaResizeKeepsConstantsAndTheMean) {
  const Tensor c = Tensor::full({3, 37, 101}, 0.7);
  EXPECT_LT(max(abs(add_scalar(area_resize(c, 8, 16), -0.7))).item(), 1e-6);
  const Tensor x = Tensor::uniform({3, 37, 101}, 0.0, 2.0, 4, DType::F64);
  const Tensor y = area_resize(x, 8, 16);
  EXPECT_EQ(y.shape(), (Shape{3, 8, 16}));
  EXPECT_NEAR(mean(y).item(), mean(x).item(), 1e-12);
  EXPECT_TRUE(area_resize(x, 37, 101).same(x));  // the identity size is no copy
}

TEST(LightingRefinement, AreaResizeAndDiscriminatorInputPassFloat64Gradcheck) {
  const Tensor x = Tensor::uniform({3, 7, 9}, 0.05, 0.6, 2, DType::F64);
  const GradcheckResult a = gradcheck([](const TensorList& in) { return area_resize(in[0], 3, 4); }, {x.clone()});
  EXPECT_TRUE(a.ok) << a.message;
  const GradcheckResult b = gradcheck([](const TensorList& in) { return area_resize(in[0], 10, 13); }, {x.clone()});
  EXPECT_TRUE(b.ok) << b.message;
  const GradcheckResult c =
      gradcheck([](const TensorList& in) { return discriminator_input(in[0], 3, 4); }, {x.clone()});
  EXPECT_TRUE(c.ok) << c.message;
}

TEST(LightingRefinement, ZeroStepsReturnTheStartLightingBitwise) {
  Scene s("refine_zero");
  const EstimatedLighting start = s.lighting(20.0, 35.0, 1.0, true);
  auto d = linear_discriminator(1.0);
  RefinementOptions r;
  r.steps = 0;
  r.volume = true;
  const RefinementResult out = s.refine(start, *d, r);
  EXPECT_TRUE(out.lighting.env.same(start.env));
  EXPECT_TRUE(out.lighting.vsg.same(start.vsg));
  EXPECT_EQ(out.lighting.sun_direction_canonical, start.sun_direction_canonical);
  EXPECT_EQ(out.lighting.sun_intensity_rgb, start.sun_intensity_rgb);
  EXPECT_EQ(out.loss_before, out.loss_after);
  EXPECT_TRUE(out.loss_per_step.empty());
}

// On a black photo the composite is the object alone (S ⊙ 0 = 0), so a D that prefers a brighter
// image prefers a brighter object. With the sun behind the camera, lighting the faces the camera
// sees, the sun intensity rises for that D and falls for the opposite one, and −D falls in both.
TEST(LightingRefinement, IntensityMovesTheWayTheDiscriminatorPrefers) {
  Scene s("refine_intensity", /*analytic_sky=*/true);
  s.view.ldr = Tensor::zeros({3, 32, 64});
  const EstimatedLighting start = s.lighting(180.0, 40.0, 0.1);
  for (double sign : {1.0, -1.0}) {
    auto d = linear_discriminator(sign);
    RefinementOptions r;
    r.steps = 6;
    r.lr = 0.1;
    r.direction = r.latent = false;
    const RefinementResult out = s.refine(start, *d, r);
    EXPECT_LT(out.loss_after, out.loss_before) << "sign " << sign;
    EXPECT_EQ(out.skipped_steps, 0);
    for (int c = 0; c < 3; ++c) {
      const double before = std::log(start.sun_intensity_rgb[c]), after = std::log(out.lighting.sun_intensity_rgb[c]);
      if (sign > 0) EXPECT_GT(after, before + 0.1) << "channel " << c;
      else EXPECT_LT(after, before - 0.1) << "channel " << c;
    }
    // Only the intensity was free: the direction is the start's.
    EXPECT_LT(glm::length(out.lighting.sun_direction_canonical - start.sun_direction_canonical), 1e-6);
  }
}

// The sun behind the camera, 30° up, lights the object's face toward the camera (normal +Z, in
// the canonical frame) as cos(elevation). On a black photo a D that prefers a brighter image
// lowers the sun toward that face's normal (its direction's z rises); one that prefers darkness
// raises it. The direction stays unit length and the intensity untouched.
TEST(LightingRefinement, DirectionMovesTheSunTheWayTheDiscriminatorPrefers) {
  Scene s("refine_direction", /*analytic_sky=*/true);
  s.view.ldr = Tensor::zeros({3, 32, 64});
  const EstimatedLighting start = s.lighting(180.0, 30.0, 0.1);
  ASSERT_GT(start.sun_direction_canonical.z, 0.5);
  for (double sign : {1.0, -1.0}) {
    auto d = linear_discriminator(sign);
    RefinementOptions r;
    r.steps = 6;
    r.lr = 0.05;
    r.intensity = r.latent = false;
    const RefinementResult out = s.refine(start, *d, r);
    EXPECT_LT(out.loss_after, out.loss_before) << "sign " << sign;
    const double dz = out.lighting.sun_direction_canonical.z - start.sun_direction_canonical.z;
    const double del = elevation_deg_of(out.lighting.sun_direction_canonical) - elevation_deg_of(start.sun_direction_canonical);
    if (sign > 0) {
      EXPECT_GT(dz, 0.01);
      EXPECT_LT(del, -1.0);
    } else {
      EXPECT_LT(dz, -0.01);
      EXPECT_GT(del, 1.0);
    }
    EXPECT_NEAR(glm::length(out.lighting.sun_direction_canonical), 1.0, 1e-6);
    EXPECT_EQ(out.lighting.sun_intensity_rgb, start.sun_intensity_rgb);
  }
}

TEST(LightingRefinement, ExtremeSunKeepsEveryOutputFinite) {
  Scene s("refine_extreme");
  EstimatedLighting probe = s.lighting(30.0, 20.0, 1.0, true);
  const double sky = mean(probe.env).item();
  const double scale = 1e5 * sky / std::max({probe.sun_intensity_rgb.x, probe.sun_intensity_rgb.y,
                                              probe.sun_intensity_rgb.z});
  const EstimatedLighting start = s.lighting(30.0, 20.0, scale, true);
  for (double sign : {1.0, -1.0}) {
    auto d = linear_discriminator(sign);
    RefinementOptions r;
    r.steps = 3;
    r.lr = 0.5;
    r.volume = true;
    const RefinementResult out = s.refine(start, *d, r);
    EXPECT_TRUE(std::isfinite(out.loss_before) && std::isfinite(out.loss_after));
    EXPECT_EQ(out.skipped_steps, 0) << "a non-finite loss or gradient under the extreme sun";
    EXPECT_TRUE(finite(out.lighting.env)) << sign;
    EXPECT_TRUE(finite(out.lighting.vsg)) << sign;
    EXPECT_TRUE(finite(out.lighting.sky_code.log_intensity) && finite(out.lighting.sky_code.dir) &&
                finite(out.lighting.sky_code.latent));
    EXPECT_NEAR(glm::length(out.lighting.sun_direction_canonical), 1.0, 1e-6);
    EXPECT_FALSE(out.lighting.vsg.same(start.vsg));
    const PhotoInsertion ins = insert_into_photo(out.lighting, s.view.ldr, s.view.depth, s.view.camera, s.object,
                                                 s.pose, s.insertion);
    EXPECT_TRUE(finite(ins.composite_linear));
  }
}

// A discriminator that scores NaN (a broken file): every step is skipped, so the lighting that
// comes back is the start's sky vector and finite.
TEST(LightingRefinement, NonFiniteLossesChangeNothing) {
  Scene s("refine_nan");
  const EstimatedLighting start = s.lighting(30.0, 30.0, 1.0);
  auto d = linear_discriminator(1.0);
  for (const auto& [name, t] : d->named_parameters()) Tensor(t).fill_(std::nan(""));
  RefinementOptions r;
  r.steps = 3;
  const RefinementResult out = s.refine(start, *d, r);
  EXPECT_EQ(out.skipped_steps, 3);
  EXPECT_LT(glm::length(out.lighting.sun_direction_canonical - start.sun_direction_canonical), 1e-6);
  EXPECT_EQ(out.lighting.sun_intensity_rgb, start.sun_intensity_rgb);
  EXPECT_EQ(out.lighting.sky_code.latent.to_vector(), start.sky_code.latent.to_vector());
  EXPECT_TRUE(finite(out.lighting.env));
}

TEST(LightingRefinement, RefusesALightingWithoutASkyVectorAndBadOptions) {
  Scene s("refine_bad");
  EstimatedLighting l = s.lighting(0.0, 30.0, 1.0);
  auto d = linear_discriminator(1.0);
  RefinementOptions r;
  r.steps = -1;
  EXPECT_THROW(s.refine(l, *d, r), Error);
  r.steps = 1;
  r.lr = 0.0;
  EXPECT_THROW(s.refine(l, *d, r), Error);
  r.lr = 0.05;
  r.volume = true;  // l has no volume
  EXPECT_THROW(s.refine(l, *d, r), Error);
  r.volume = false;
  l.has_sky_code = false;
  EXPECT_THROW(s.refine(l, *d, r), Error);
}

// load_discriminator builds D from the file's config and its discriminator.* tensors, and
// reports a file without them as "none".
TEST(LightingRefinement, LoadDiscriminatorRoundTripsAndReportsNone) {
  const std::string dir = tool_dir("refine_load");
  nlohmann::json c = tiny_lighting_config();
  c["stage"] = "adversarial";
  c["model"]["discriminator"] = {{"base_channels", 4}, {"layers", 2}, {"norm", "instance"}};
  auto d = std::make_shared<nn::PatchDiscriminator>(
      nn::PatchDiscriminatorOptions{.base_channels = 4, .layers = 2, .norm = "instance"});
  d->init_parameters(11);
  nn::Module holder("LightingModel");
  holder.register_module("predictor", std::make_shared<LightingPredictor>(predictor_options(c)));
  holder.register_module("discriminator", d);
  const std::string path = dir + "/adv.safetensors";
  nn::save_checkpoint(path, holder, nullptr, nn::CheckpointInfo{.stage = "adversarial", .step = 1, .config_json = c.dump()});
  const auto loaded = load_discriminator(path);
  ASSERT_TRUE(loaded);
  d->eval();
  const Tensor x = Tensor::uniform({1, 3, 32, 64}, 0.0, 1.0, 9);
  EXPECT_LT(max(abs(sub(loaded->forward(x), d->forward(x)))).item(), 1e-6);
  EXPECT_FALSE(load_discriminator(tiny_lighting_checkpoint(dir)));
}

}  // namespace

}  // namespace sl::test
