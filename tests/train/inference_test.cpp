// train/inference.h: frames, sun editing and multi-view fusion on a random-weight tiny model.
#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "support/tool_fixture.h"
#include "train/inference.h"
#include "train/photo_insertion.h"
#include "util/math.h"

namespace {

using namespace sl;
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

}  // namespace
