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

// A sky-model panorama with its sun at (elevation, azimuth), and crops of width × width/2 made
// into training items without the volume.
struct CropSetup {
  Tensor pano;
  data::PanoramaSampleOptions crop;
  render::VsgGrid grid;
  train::StreetBatchOptions batch;
  CropSetup(double elevation_deg, double azimuth_rad, int width) {
    data::SkyParams p;
    p.sun_elevation_rad = elevation_deg * kPi / 180.0;
    p.sun_azimuth_rad = azimuth_rad;
    pano = data::PreethamSky(p).render(2 * width, 4 * width);
    crop.crop.width = width;
    crop.crop.height = width / 2;
    crop.pano_width = 2 * width;
    crop.pano_height = width;
    grid.dims = {8, 8, 4};
    batch.need_volume = false;
    batch.image_height = width / 2;
    batch.image_width = width;
  }
  data::StreetSample sample(uint64_t stream) const { return data::panorama_street_sample(pano, "p", 3, stream, crop); }
  train::StreetItem item(const data::StreetSample& s, uint64_t stream) const {
    return train::make_street_item(s, 0, grid, batch, 1, stream);
  }
};

TEST(SunLabelFrame, LabelLandsOnTheCropsBrightestPixel) {
  const CropSetup c(6.0, 0.7, 128);
  int seen = 0;
  for (uint64_t stream = 0; stream < 400 && seen < 6; ++stream) {
    const data::StreetSample s = c.sample(stream);
    const train::StreetItem it = c.item(s, stream);
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
  const CropSetup c(8.0, -0.4, 64);
  int in_front = 0;
  for (uint64_t stream = 0; stream < 8; ++stream) {
    const data::StreetSample s = c.sample(stream);
    const train::StreetItem a = c.item(s, stream);
    const train::StreetItem b = c.item(data::flip_sample(s), stream);
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
