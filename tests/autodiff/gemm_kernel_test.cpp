// The packed float GEMM (autodiff/gemm_kernel.h) as matmul uses it: forward C = A·B and both
// gradients, Aᵀ·G and G·Bᵀ, on shapes with a partial last column panel and a partial last row
// block, against the same products in float64.
//
// Bound: each element of the float result is one sequence of K fused multiply-adds in float from
// zero, so (Higham, Accuracy and Stability of Numerical Algorithms, §3.1, with one rounding per
// FMA) |c − ĉ| ≤ γ_K · Σ_k |a_ik b_kj| with γ_K = K·u / (1 − K·u), u = 2⁻²⁴. The float64
// reference's own error is below 2⁻²⁹ of that and is ignored. The bound is of the arithmetic, not
// of one CPU: Eigen's float path (no packed kernel) meets it too.
#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/gemm_kernel.h"
#include "autodiff/ops.h"
#include "support/test_util.h"

namespace sl::test {
namespace {

double gamma_k(int64_t k) {
  const double u = std::ldexp(1.0, -24);
  return k * u / (1.0 - k * u);
}

// Worst ratio of |float − float64| to the γ_K bound over every element of a [M, N] product of
// a [M, K] and b [K, N] (row-major float64 copies of the float inputs).
double worst_ratio(const std::vector<double>& got, const std::vector<double>& a, const std::vector<double>& b,
                   int64_t M, int64_t N, int64_t K) {
  double worst = 0.0;
  for (int64_t i = 0; i < M; ++i)
    for (int64_t j = 0; j < N; ++j) {
      double exact = 0.0, magnitude = 0.0;
      for (int64_t k = 0; k < K; ++k) {
        exact += a[i * K + k] * b[k * N + j];
        magnitude += std::fabs(a[i * K + k] * b[k * N + j]);
      }
      const double bound = gamma_k(K) * magnitude + 1e-300;
      worst = std::max(worst, std::fabs(got[i * N + j] - exact) / bound);
    }
  return worst;
}

std::vector<double> transposed(const std::vector<double>& x, int64_t rows, int64_t cols) {
  std::vector<double> t(x.size());
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t c = 0; c < cols; ++c) t[c * rows + r] = x[r * cols + c];
  return t;
}

TEST(GemmKernel, MatmulAndItsWeightGradientStayWithinTheFmaBound) {
  if (!detail::gemm_kernel_available()) GTEST_SKIP() << "no AVX2 + FMA or AVX-512: matmul runs on Eigen here";
  // M: full and partial 8-row blocks, more than one 256-row task; N: full panels plus a tail of
  // 5 columns (the padded copy); K: odd. Every shape has the 2^18 multiply-adds that select the
  // packed path (autodiff/matmul.cpp use_packed).
  for (const auto& [M, K, N] : {std::tuple<int64_t, int64_t, int64_t>{37, 129, 101}, {300, 67, 53}, {8, 700, 48}}) {
    SCOPED_TRACE("M " + std::to_string(M) + " K " + std::to_string(K) + " N " + std::to_string(N));
    Tensor a = Tensor::uniform({M, K}, -1, 1, 3, DType::F32).set_requires_grad(true);
    Tensor b = Tensor::uniform({K, N}, -1, 1, 4, DType::F32).set_requires_grad(true);
    Tensor g = Tensor::uniform({M, N}, -1, 1, 5, DType::F32);
    Tensor c = matmul(a, b);
    backward(sum(mul(c, g)));
    const std::vector<double> av = a.to_vector(), bv = b.to_vector(), gv = g.to_vector();
    EXPECT_LE(worst_ratio(c.to_vector(), av, bv, M, N, K), 1.0) << "C = A·B";
    // dB = Aᵀ·G: A transposed in the packing ([K, M] · [M, N]).
    EXPECT_LE(worst_ratio(b.grad().to_vector(), transposed(av, M, K), gv, K, N, M), 1.0) << "dB = Aᵀ·G";
    // dA = G·Bᵀ: B rewritten as transposed, zero-padded panels ([M, N] · [N, K]).
    EXPECT_LE(worst_ratio(a.grad().to_vector(), gv, transposed(bv, K, N), M, K, N), 1.0) << "dA = G·Bᵀ";
  }
}

TEST(GemmKernel, PanelsOfOneMatrixGiveTheBitsOfTheWholeProduct) {
  if (!detail::gemm_kernel_available()) GTEST_SKIP() << "no AVX2 + FMA or AVX-512";
  // Each element is one FMA sequence over k whatever the panel or row block it is computed in:
  // a product's top-left 16 × 48 corner (itself large enough for the packed path) equals the product of the corner's own rows and columns.
  Tensor a = Tensor::uniform({64, 400}, -1, 1, 6, DType::F32), b = Tensor::uniform({400, 200}, -1, 1, 7, DType::F32);
  const std::vector<double> whole = matmul(a, b).to_vector();
  const std::vector<double> corner =
      matmul(slice(a, 0, 0, 16).contiguous(), slice(b, 1, 0, 48).contiguous()).to_vector();
  for (int64_t i = 0; i < 16; ++i)
    for (int64_t j = 0; j < 48; ++j) ASSERT_EQ(corner[i * 48 + j], whole[i * 200 + j]) << i << ", " << j;
}

// The 8 × 32 tile of gemm_panel_narrow gives the bits of the 48-column tile on the columns both
// compute, with and without a bias, for every width up to 32 and a partial last row block; B's
// panel has 48 floats per row (the AVX2 path reads all of them).
TEST(GemmKernel, NarrowPanelGivesTheBitsOfTheFullPanel) {
  if (!detail::gemm_kernel_available()) GTEST_SKIP() << "no AVX2 + FMA or AVX-512";
  const int64_t M = 21, K = 300, cols = detail::kPanelCols;
  const std::vector<double> ad = Tensor::uniform({M * K}, -1, 1, 8).to_vector();
  const std::vector<double> bd = Tensor::uniform({K * cols}, -1, 1, 9).to_vector();
  const std::vector<double> biasd = Tensor::uniform({M}, -1, 1, 10).to_vector();
  const std::vector<float> a(ad.begin(), ad.end()), b(bd.begin(), bd.end()), bias(biasd.begin(), biasd.end());
  const detail::PackedRows packed = detail::pack_rows(a.data(), M, K);
  for (const float* bi : {static_cast<const float*>(nullptr), bias.data()})
    for (int64_t n : {1, 7, 16, 17, 31, 32}) {
      std::vector<float> full(static_cast<size_t>(M * cols), 0.0f), narrow(static_cast<size_t>(M * cols), 0.0f);
      detail::gemm_panel(packed.data(), M, K, b.data(), n, bi, full.data(), cols);
      detail::gemm_panel_narrow(packed.data(), M, K, b.data(), n, bi, narrow.data(), cols, cols);
      EXPECT_EQ(full, narrow) << "n = " << n << (bi ? " with bias" : "");
    }
}

}  // namespace
}  // namespace sl::test
