// dropout: counter-based mask (same bits for any thread count), scaling, eval identity, gradcheck.
#include "nn/functional/dropout.h"

#include <gtest/gtest.h>
#include <omp.h>

#include "support/test_util.h"

namespace sl::test {
using nn::dropout;

namespace {

TEST(Dropout, EvalAndZeroProbabilityReturnTheInput) {
  const Tensor x = Tensor::ones({3, 4});
  EXPECT_TRUE(dropout(x, 0.5, false, 1, 0).same(x));
  EXPECT_TRUE(dropout(x, 0.0, true, 1, 0).same(x));
}

TEST(Dropout, KeepsAboutOneMinusPAndScalesKeptValues) {
  const Tensor y = dropout(Tensor::ones({100000}), 0.3, true, 7, 2);
  int64_t kept = 0;
  for (double v : y.to_vector()) {
    if (v != 0) {
      ++kept;
      EXPECT_FLOAT_EQ(v, 1.0 / 0.7);
    }
  }
  EXPECT_NEAR(static_cast<double>(kept) / 100000.0, 0.7, 0.01);
}

TEST(Dropout, MaskDependsOnSeedAndStepNotOnThreads) {
  const Tensor x = Tensor::ones({50000});
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto a = dropout(x, 0.5, true, 3, 9).to_vector();
  omp_set_num_threads(2);
  const auto b = dropout(x, 0.5, true, 3, 9).to_vector();
  omp_set_num_threads(saved);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, dropout(x, 0.5, true, 3, 10).to_vector());
  EXPECT_NE(a, dropout(x, 0.5, true, 4, 9).to_vector());
}

TEST(Dropout, GradcheckReplaysTheMask) {
  EXPECT_GRADCHECK([](const TensorList& in) { return dropout(in[0], 0.4, true, 5, 1); },
                   {sl::test::rand64({3, 5}, 1)});
}

TEST(Dropout, RejectsProbabilityOutsideZeroOne) {
  EXPECT_THROW(dropout(Tensor::ones({2}), 1.0, true, 0, 0), Error);
  EXPECT_THROW(dropout(Tensor::ones({2}), -0.1, true, 0, 0), Error);
}

}  // namespace
}  // namespace sl::test
