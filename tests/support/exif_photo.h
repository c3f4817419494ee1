// A camera photo as a phone writes one, for the tests of EXIF handling (data/image_io.h,
// train/photo_input.h): 8-bit stored rows with an EXIF Orientation tag and, when focal_35mm > 0,
// a 35 mm-equivalent focal length. The format follows the extension (.jpg, .tif).
#pragma once
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "autodiff/tensor.h"
#include "util/error.h"

namespace sl::test {

// stored: [C, H, W] values in [0, 1], written as codes round(255 · v) in the stored row order.
inline void write_exif_photo(const std::string& path, const Tensor& stored, int orientation, int focal_35mm = 0) {
  const int c = static_cast<int>(stored.size(0)), h = static_cast<int>(stored.size(1)),
            w = static_cast<int>(stored.size(2));
  const std::vector<double> v = stored.to_vector();
  std::vector<unsigned char> px(static_cast<size_t>(c) * h * w);
  for (int ch = 0; ch < c; ++ch)
    for (int i = 0; i < h * w; ++i)
      px[static_cast<size_t>(i) * c + ch] =
          static_cast<unsigned char>(std::lround(255.0 * std::clamp(v[static_cast<size_t>(ch) * h * w + i], 0.0, 1.0)));
  OIIO::ImageSpec spec(w, h, c, OIIO::TypeDesc::UINT8);
  spec.attribute("Orientation", orientation);
  if (focal_35mm > 0) spec.attribute("Exif:FocalLengthIn35mmFilm", focal_35mm);
  if (path.ends_with(".jpg")) spec.attribute("Compression", "jpeg:100");
  auto out = OIIO::ImageOutput::create(path);
  SL_CHECK(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data()) && out->close(),
           "write_exif_photo: cannot write ", path);
}

}  // namespace sl::test
