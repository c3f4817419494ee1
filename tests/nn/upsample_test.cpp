// Upsampling: float64 gradchecks for every mode and align_corners, exact values on small cases.
#include "nn/functional/upsample.h"

#include <gtest/gtest.h>

#include "support/test_util.h"

namespace sl::test {
using nn::upsample_bilinear2d;
using nn::upsample_nearest2d;
using nn::upsample_nearest3d;
using nn::upsample_trilinear3d;

namespace {

TEST(Upsample, NearestRepeatsEachPixel) {
  const Tensor x = reshape(Tensor::arange(4, DType::F64), {1, 1, 2, 2});
  EXPECT_EQ(upsample_nearest2d(x, 2).to_vector(),
            (std::vector<double>{0, 0, 1, 1, 0, 0, 1, 1, 2, 2, 3, 3, 2, 2, 3, 3}));
}

TEST(Upsample, BilinearHalfPixelAndAlignCornersValues) {
  const Tensor x = Tensor::from_vector({0, 1}, {1, 1, 1, 2}, DType::F64);
  // align_corners=false, scale 2: sources -0.25 (clamped to 0), 0.25, 0.75, 1.25 (edge).
  EXPECT_EQ(upsample_bilinear2d(x, 2).to_vector(), (std::vector<double>{0, 0.25, 0.75, 1, 0, 0.25, 0.75, 1}));
  const auto ac = upsample_bilinear2d(x, 2, true).to_vector();  // sources 0, 1/3, 2/3, 1
  EXPECT_NEAR(ac[5], 1.0 / 3.0, 1e-15);
  EXPECT_NEAR(ac[7], 1.0, 1e-15);
}

TEST(Upsample, GradcheckAllModes) {
  for (bool ac : {false, true}) {
    EXPECT_GRADCHECK([ac](const TensorList& in) { return upsample_bilinear2d(in[0], 2, ac); },
                     {rand64({2, 2, 3, 1}, 1)});
    EXPECT_GRADCHECK([ac](const TensorList& in) { return upsample_trilinear3d(in[0], 2, ac); },
                     {rand64({1, 2, 2, 3, 2}, 2)});
  }
  EXPECT_GRADCHECK([](const TensorList& in) { return upsample_nearest2d(in[0], 3); }, {rand64({1, 2, 2, 3}, 3)});
  EXPECT_GRADCHECK([](const TensorList& in) { return upsample_nearest3d(in[0], 2); },
                   {rand64({1, 1, 2, 1, 3}, 4)});
}

TEST(Upsample, GradcheckNonContiguousInput) {
  const Tensor x = permute(rand64({1, 3, 4, 2}, 5), {0, 3, 2, 1});  // [1, 2, 4, 3]
  EXPECT_GRADCHECK([](const TensorList& in) { return upsample_bilinear2d(in[0], 3); }, {x});
}

TEST(Upsample, ErrorsNameTheOp) {
  EXPECT_THROW(upsample_nearest2d(Tensor::zeros({1, 1, 2}), 2), Error);
  EXPECT_THROW(upsample_trilinear3d(Tensor::zeros({1, 1, 2, 2}), 2), Error);
  EXPECT_THROW(upsample_bilinear2d(Tensor::zeros({1, 1, 2, 2}), 0), Error);
}

}  // namespace
}  // namespace sl::test
