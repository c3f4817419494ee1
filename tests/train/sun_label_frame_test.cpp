// The sun label of a training item and its input image agree: in the item's canonical frame, the
// label seen through the item's camera lands on the crop's brightest pixel, and the canonical
// panorama's peak is the label.
#include <gtest/gtest.h>

#include <cmath>

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

}  // namespace
}  // namespace sl::test
