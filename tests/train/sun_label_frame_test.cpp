// The sun label of a training item and its input image agree: in the item's canonical frame, the
// label seen through the item's camera lands on the crop's brightest pixel, and the canonical
// panorama's peak is the label.
#include <gtest/gtest.h>

#include <cmath>

#include "data/augment.h"
#include "data/panorama.h"
#include "data/panorama_sample.h"
#include "data/sky_model.h"
#include "data/sun_extraction.h"
#include "render/camera.h"
#include "train/street_batch.h"
#include "util/math.h"

namespace sl::test {
namespace {

TEST(SunLabelFrame, LabelLandsOnTheCropsBrightestPixel) {
  data::SkyParams p;
  p.sun_elevation_rad = 6.0 * kPi / 180.0;
  p.sun_azimuth_rad = 0.7;
  const Tensor pano = data::PreethamSky(p).render(256, 512);
  data::PanoramaSampleOptions o;
  o.crop.width = 128;
  o.crop.height = 64;
  o.pano_width = 256;
  o.pano_height = 128;
  render::VsgGrid grid;
  grid.dims = {8, 8, 4};
  train::StreetBatchOptions bo;
  bo.need_volume = false;
  bo.image_height = 64;
  bo.image_width = 128;
  int seen = 0;
  for (uint64_t stream = 0; stream < 400 && seen < 6; ++stream) {
    const data::StreetSample s = data::panorama_street_sample(pano, "p", 3, stream, o);
    const train::StreetItem it = train::make_street_item(s, 0, grid, bo, 1, stream);
    const render::Projection pr = it.camera.project(it.camera.position() + it.sun_direction * 1e4);
    const Tensor hdr = s.views[0].hdr.contiguous();
    const int64_t h = hdr.size(1), w = hdr.size(2);
    const float* d = hdr.data<float>();
    int64_t best = 0;
    for (int64_t i = 0; i < h * w; ++i)
      if (d[i] + d[h * w + i] + d[2 * h * w + i] > d[best] + d[h * w + best] + d[2 * h * w + best]) best = i;
    const double bu = best % w + 0.5, bv = best / w + 0.5;
    const glm::dvec3 cam_sun = it.camera.world_to_camera(it.camera.position() + it.sun_direction * 1e4);
    if (cam_sun.z <= 0 || !pr.in_image) continue;
    ++seen;
    EXPECT_NEAR(pr.pixel.x, bu, 3.0) << "stream " << stream;
    EXPECT_NEAR(pr.pixel.y, bv, 3.0) << "stream " << stream;
    const glm::dvec3 peak = data::extract_sun(it.frame.panorama(s.pano_hdr.contiguous())).direction;
    EXPECT_GT(glm::dot(peak, it.sun_direction), std::cos(3.0 * kPi / 180.0));
  }
  EXPECT_GT(seen, 2);
}

// data.flip's mirrored sample gives the mirrored training item: in the canonical frame the sun
// label's x flips, the input image is the mirror image, and the label lands at (W − u, v).
TEST(SunLabelFrame, FlippedSampleGivesTheMirroredItem) {
  data::SkyParams p;
  p.sun_elevation_rad = 8.0 * kPi / 180.0;
  p.sun_azimuth_rad = -0.4;
  const Tensor pano = data::PreethamSky(p).render(128, 256);
  data::PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 128;
  o.pano_height = 64;
  render::VsgGrid grid;
  grid.dims = {8, 8, 4};
  train::StreetBatchOptions bo;
  bo.need_volume = false;
  bo.image_height = 32;
  bo.image_width = 64;
  int in_front = 0;
  for (uint64_t stream = 0; stream < 8; ++stream) {
    const data::StreetSample s = data::panorama_street_sample(pano, "p", 3, stream, o);
    const train::StreetItem a = train::make_street_item(s, 0, grid, bo, 1, stream);
    const train::StreetItem b = train::make_street_item(data::flip_sample(s), 0, grid, bo, 1, stream);
    EXPECT_NEAR(b.sun_direction.x, -a.sun_direction.x, 1e-9) << stream;
    EXPECT_NEAR(b.sun_direction.y, a.sun_direction.y, 1e-9) << stream;
    EXPECT_NEAR(b.sun_direction.z, a.sun_direction.z, 1e-9) << stream;
    EXPECT_EQ(b.image.to_vector(), data::flip_horizontal(a.image).to_vector()) << stream;
    const render::Projection pa = a.camera.project(a.camera.position() + a.sun_direction * 1e4);
    const render::Projection pb = b.camera.project(b.camera.position() + b.sun_direction * 1e4);
    ASSERT_EQ(pb.in_front, pa.in_front) << stream;
    if (!pa.in_front) continue;
    ++in_front;
    EXPECT_NEAR(pb.pixel.x, 64 - pa.pixel.x, 1e-6) << stream;
    EXPECT_NEAR(pb.pixel.y, pa.pixel.y, 1e-6) << stream;
  }
  EXPECT_GT(in_front, 0);
}

}  // namespace
}  // namespace sl::test
