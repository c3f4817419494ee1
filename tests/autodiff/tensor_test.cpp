#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "support/test_util.h"

namespace sl::test {
namespace {

TEST(Tensor, StorageIs64ByteAlignedForEveryDtype) {
  for (DType dt : {DType::F32, DType::F64, DType::I64}) {
    Tensor t = Tensor::zeros({3, 5, 7}, dt);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(t.storage()->data()) % 64, 0u);
  }
}

TEST(Tensor, SupportsSixAndMoreDimsAndZeroSizedDims) {
  Tensor t = Tensor::ones({2, 1, 3, 1, 2, 2, 1}, DType::F64);
  EXPECT_EQ(t.dim(), 7);
  EXPECT_EQ(t.numel(), 24);
  EXPECT_DOUBLE_EQ(sum(t).item(), 24.0);
  Tensor e = Tensor::zeros({3, 0, 2});
  EXPECT_EQ(e.numel(), 0);
  EXPECT_EQ(sum(e, {1}).shape(), (Shape{3, 2}));
  EXPECT_DOUBLE_EQ(sum(e).item(), 0.0);
}

TEST(Tensor, PermuteAndSliceAreViewsSharingStorage) {
  Tensor t = Tensor::arange(24, DType::F64);
  Tensor m = reshape(t, {2, 3, 4});
  EXPECT_EQ(m.storage(), t.storage());
  Tensor p = permute(m, {2, 0, 1});
  EXPECT_EQ(p.storage(), t.storage());
  EXPECT_FALSE(p.is_contiguous());
  EXPECT_DOUBLE_EQ(p.at({3, 1, 2}), m.at({1, 2, 3}));
  Tensor s = slice(m, 2, 1, 4, 2);
  EXPECT_EQ(s.shape(), (Shape{2, 3, 2}));
  EXPECT_DOUBLE_EQ(s.at({1, 2, 1}), m.at({1, 2, 3}));
  Tensor c = p.contiguous();
  EXPECT_NE(c.storage(), t.storage());
  EXPECT_TRUE(c.is_contiguous());
  EXPECT_EQ(c.to_vector(), p.to_vector());
}

TEST(Tensor, CloneIsAnExplicitCopy) {
  Tensor a = Tensor::ones({4}, DType::F32);
  Tensor b = a.clone();
  b.fill_(2.0);
  EXPECT_DOUBLE_EQ(a.at({0}), 1.0);
  EXPECT_DOUBLE_EQ(b.at({0}), 2.0);
}

TEST(Tensor, DtypeConversionRoundTrips) {
  Tensor a = Tensor::from_vector({1.5, -2.25, 3.0}, {3}, DType::F32);
  Tensor b = a.to(DType::F64);
  EXPECT_EQ(b.dtype(), DType::F64);
  EXPECT_EQ(b.to_vector(), (std::vector<double>{1.5, -2.25, 3.0}));
}

TEST(Tensor, ShapeMismatchErrorNamesOpAndBothShapes) {
  Tensor a = Tensor::zeros({2, 3}), b = Tensor::zeros({4, 3});
  try {
    add(a, b);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("add"), std::string::npos) << m;
    EXPECT_NE(m.find("[2, 3]"), std::string::npos) << m;
    EXPECT_NE(m.find("[4, 3]"), std::string::npos) << m;
  }
  try {
    matmul(Tensor::zeros({2, 3}), Tensor::zeros({4, 5}));
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("matmul"), std::string::npos) << m;
    EXPECT_NE(m.find("[2, 3]"), std::string::npos) << m;
    EXPECT_NE(m.find("[4, 5]"), std::string::npos) << m;
  }
}

TEST(Tensor, MixedDtypesAreAnErrorNotASilentCast) {
  EXPECT_THROW(mul(Tensor::zeros({2}, DType::F32), Tensor::zeros({2}, DType::F64)), Error);
}

TEST(Tensor, ReshapeInfersOneDimAndRejectsBadSizes) {
  Tensor t = Tensor::zeros({2, 3, 4});
  EXPECT_EQ(reshape(t, {-1, 4}).shape(), (Shape{6, 4}));
  EXPECT_THROW(reshape(t, {5, -1}), Error);
  EXPECT_THROW(reshape(t, {-1, -1}), Error);
}

TEST(Tensor, CounterBasedRandomIsAPureFunctionOfSeed) {
  Tensor a = Tensor::uniform({1000}, 0, 1, 42), b = Tensor::uniform({1000}, 0, 1, 42);
  Tensor c = Tensor::uniform({1000}, 0, 1, 43);
  EXPECT_EQ(a.to_vector(), b.to_vector());
  EXPECT_NE(a.to_vector(), c.to_vector());
  const double m = mean(a).item();
  EXPECT_NEAR(m, 0.5, 0.05);
}

TEST(Tensor, IndexOutOfRangeIsAnError) {
  Tensor x = Tensor::zeros({3, 2}, DType::F64);
  EXPECT_THROW(index_select(x, 0, Tensor::from_indices({0, 3}, {2})), Error);
  EXPECT_THROW(gather(x, 1, Tensor::from_indices({0, -1, 0, 0, 0, 0}, {3, 2})), Error);
  EXPECT_THROW(x.at({3, 0}), Error);
}

}  // namespace
}  // namespace sl::test
