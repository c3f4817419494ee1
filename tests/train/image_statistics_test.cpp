// The sun head's photometric statistics (train/image_statistics.h): each of the 102 numbers on
// images whose values are known, the mirror relation, and the shape errors.
#include "train/image_statistics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "util/error.h"

namespace sl::test {
using train::image_statistics;
using train::kImageStatistics;

namespace {

// [1, 3, h, w] from a function of (channel, row, column).
template <class F>
Tensor make_image(int64_t h, int64_t w, F f, DType dtype = DType::F32) {
  std::vector<double> v;
  for (int c = 0; c < 3; ++c)
    for (int64_t y = 0; y < h; ++y)
      for (int64_t x = 0; x < w; ++x) v.push_back(f(c, y, x));
  return Tensor::from_vector(v, {1, 3, h, w}, dtype);
}

}  // namespace

// Left half black, right half white (saturated), and a blue channel that alternates by row
// in the bottom half: every number of the layout is checked.
TEST(ImageStatistics, EachNumberOfAKnownImage) {
  const int64_t h = 8, w = 16;
  const Tensor image = make_image(h, w, [&](int c, int64_t y, int64_t x) {
    if (c == 2 && y >= h / 2) return y % 2 == 0 ? 1.0 : 0.0;
    return x >= w / 2 ? 1.0 : 0.0;
  });
  const Tensor s = image_statistics(image);
  ASSERT_EQ(s.shape(), (Shape{1, kImageStatistics}));
  const std::vector<double> v = s.to_vector();
  for (int gy = 0; gy < 4; ++gy)
    for (int gx = 0; gx < 4; ++gx) {
      const int cell = gy * 4 + gx;
      const double side = gx >= 2 ? 1.0 : 0.0;
      EXPECT_DOUBLE_EQ(v[cell * 3 + 0], side) << cell;
      EXPECT_DOUBLE_EQ(v[cell * 3 + 1], side) << cell;
      EXPECT_DOUBLE_EQ(v[48 + cell * 3 + 0], 0.0) << cell;
      if (gy >= 2) {  // alternating rows: mean 1/2, spread 1/2
        EXPECT_DOUBLE_EQ(v[cell * 3 + 2], 0.5) << cell;
        EXPECT_NEAR(v[48 + cell * 3 + 2], 0.5, 1e-6) << cell;
      } else {
        EXPECT_DOUBLE_EQ(v[cell * 3 + 2], side) << cell;
        EXPECT_DOUBLE_EQ(v[48 + cell * 3 + 2], 0.0) << cell;
      }
    }
  // Brightness right minus left: top rows 1 - 0; bottom rows (2 + b)/3 - b/3 with b = 1/2 on
  // average: 2/3. Mean over the halves: 5/6. Top minus bottom: top mean 1/2, bottom mean 1/2.
  EXPECT_NEAR(v[96], (1.0 + 2.0 / 3.0) / 2.0, 1e-6);
  EXPECT_NEAR(v[97], 0.0, 1e-6);
  // Saturated shares per quadrant: the right quadrants are white; the bottom left has blue = 1
  // on every other row.
  EXPECT_DOUBLE_EQ(v[98], 0.0);
  EXPECT_DOUBLE_EQ(v[99], 1.0);
  EXPECT_DOUBLE_EQ(v[100], 0.5);
  EXPECT_DOUBLE_EQ(v[101], 1.0);
}

// Mirroring the image mirrors the cells and quadrants and negates right-minus-left; a batch is
// image by image; float64 gives the same numbers; values outside [0, 1] are clamped.
TEST(ImageStatistics, MirrorBatchDtypeAndClamping) {
  const int64_t h = 12, w = 20;  // 20 is divisible by 4, 12 too
  const auto f = [](int c, int64_t y, int64_t x) { return 0.5 + 0.45 * std::sin(0.7 * x + 1.3 * y + c); };
  const Tensor image = make_image(h, w, f);
  const std::vector<double> a = image_statistics(image).to_vector();
  const std::vector<double> m = image_statistics(unsqueeze(data::flip_horizontal(select(image, 0, 0).contiguous()), 0)).to_vector();
  for (int gy = 0; gy < 4; ++gy)
    for (int gx = 0; gx < 4; ++gx)
      for (int c = 0; c < 3; ++c) {
        const int i = (gy * 4 + gx) * 3 + c, j = (gy * 4 + 3 - gx) * 3 + c;
        EXPECT_NEAR(m[i], a[j], 1e-6);
        EXPECT_NEAR(m[48 + i], a[48 + j], 1e-6);
      }
  EXPECT_NEAR(m[96], -a[96], 1e-6);
  EXPECT_NEAR(m[97], a[97], 1e-6);
  EXPECT_EQ(m[98], a[99]);
  EXPECT_EQ(m[100], a[101]);

  const Tensor other = make_image(h, w, [](int, int64_t, int64_t) { return 0.25; });
  const std::vector<double> both = image_statistics(concat({image, other}, 0)).to_vector();
  ASSERT_EQ(both.size(), 2 * static_cast<size_t>(kImageStatistics));
  for (int64_t i = 0; i < kImageStatistics; ++i) EXPECT_EQ(both[i], a[i]) << i;
  EXPECT_EQ(both[kImageStatistics], 0.25);

  const Tensor image64 = make_image(h, w, f, DType::F64);
  const Tensor s64 = image_statistics(image64);
  EXPECT_EQ(s64.dtype(), DType::F64);
  const std::vector<double> b = s64.to_vector();
  for (int64_t i = 0; i < kImageStatistics; ++i) EXPECT_NEAR(b[i], a[i], 1e-6) << i;

  const std::vector<double> wild =
      image_statistics(make_image(h, 16, [](int, int64_t, int64_t x) { return x % 2 ? 1e6 : -3.0; })).to_vector();
  for (double x : wild) EXPECT_TRUE(std::isfinite(x));
  EXPECT_DOUBLE_EQ(wild[0], 0.5);
  EXPECT_DOUBLE_EQ(wild[48], 0.5);
}

TEST(ImageStatistics, RejectsOtherShapesNamingThem) {
  for (const Shape& bad : {Shape{3, 8, 8}, Shape{1, 1, 8, 8}, Shape{1, 3, 3, 8}}) {
    try {
      (void)image_statistics(Tensor::zeros(bad));
      ADD_FAILURE() << "accepted " << Tensor::zeros(bad).describe();
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("image_statistics"), std::string::npos) << e.what();
    }
  }
}

}  // namespace sl::test
