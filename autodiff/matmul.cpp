// Eigen's own threading is off: panels are split here in a fixed way so that the bits of the
// result never depend on the number of threads.
#define EIGEN_DONT_PARALLELIZE
#include "autodiff/matmul.h"

#include <Eigen/Core>

#include "autodiff/elementwise.h"
#include "autodiff/gemm_kernel.h"
#include "autodiff/reduce.h"
#include "autodiff/shape_ops.h"
#include "autodiff/tape.h"
#include "autodiff/transpose16.h"
#include "util/parallel.h"

namespace sl {
namespace detail {

namespace {
constexpr int64_t kPanel = 128;  // rows (or columns) of C per independent single-threaded GEMM

template <class T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <class T>
using ConstMap = Eigen::Map<const RowMat<T>, Eigen::Unaligned, Eigen::OuterStride<>>;
template <class T>
using MutMap = Eigen::Map<RowMat<T>, Eigen::Unaligned, Eigen::OuterStride<>>;

template <class T>
void gemm_serial(bool ta, bool tb, int64_t M, int64_t N, int64_t K, T alpha, const T* A, int64_t lda,
                 const T* B, int64_t ldb, T beta, T* C, int64_t ldc) {
  MutMap<T> c(C, M, N, Eigen::OuterStride<>(ldc));
  if (K == 0) {
    if (beta == T(0)) c.setZero();
    else c *= beta;
    return;
  }
  // op(A) is M×K: stored M×K (lda) or, transposed, K×M (lda).
  const ConstMap<T> a(A, ta ? K : M, ta ? M : K, Eigen::OuterStride<>(lda));
  const ConstMap<T> b(B, tb ? N : K, tb ? K : N, Eigen::OuterStride<>(ldb));
  if (beta == T(0)) c.setZero();
  else if (beta != T(1)) c *= beta;
  if (!ta && !tb) c.noalias() += alpha * a * b;
  else if (!ta && tb) c.noalias() += alpha * a * b.transpose();
  else if (ta && !tb) c.noalias() += alpha * a.transpose() * b;
  else c.noalias() += alpha * a.transpose() * b.transpose();
}

// Rows of C per task of the packed path: a block of packed A (kPackedRows × K) is reused across
// every column panel of a task range before the next block is read.
constexpr int64_t kPackedRows = 256;

// op(B) = Bᵀ for B stored [N, K] (leading dimension ldb), written as [K][Np] with Np = N rounded
// up to whole 48-column panels and zeros past N: the layout the kernel streams.
CachedFloats transposed_panels(const float* B, int64_t ldb, int64_t N, int64_t K, int64_t Np) {
  CachedFloats bt = cached_floats(K * Np);
  parallel_for(Np / kPanelCols, std::max<int64_t>(1, (int64_t{1} << 16) / std::max<int64_t>(K * kPanelCols, 1)),
               [&](int64_t p0, int64_t p1) {
                 for (int64_t p = p0; p < p1; ++p) {
                   const int64_t j0 = p * kPanelCols, rows = std::min(kPanelCols, N - j0);
                   float* dst = bt.get() + j0;
#if defined(__AVX512F__)
                   transpose_copy(B + j0 * ldb, ldb, rows, K, dst, Np);
#else
                   for (int64_t j = 0; j < rows; ++j)
                     for (int64_t k = 0; k < K; ++k) dst[k * Np + j] = B[(j0 + j) * ldb + k];
#endif
                   if (rows < kPanelCols)
                     for (int64_t k = 0; k < K; ++k) std::fill(dst + k * Np + rows, dst + k * Np + kPanelCols, 0.0f);
                 }
               });
  return bt;
}

// C = op(A) · op(B) through the packed kernel (autodiff/gemm_kernel.h): A packed once, then tasks
// of kPackedRows rows × one 48-column panel. The kernel reads 48 floats per row of B, so the last
// panel of an untransposed B, when narrower, is copied into a zero-padded [K][48] block; a
// transposed B is rewritten whole into padded panels (transposed_panels). Each element of C is
// the kernel's one FMA sequence over k, so the bits depend neither on threads nor on the task
// split, and are the same with AVX-512 and AVX2 (they differ from Eigen's).
void packed_gemm(bool ta, bool tb, int64_t M, int64_t N, int64_t K, const float* A, const float* B, int64_t ldb,
                 float* C, int64_t ldc) {
  const PackedRows a = ta ? pack_rows_transposed(A, K, M) : pack_rows(A, M, K);
  const int64_t panels = (N + kPanelCols - 1) / kPanelCols, tail = N - (panels - 1) * kPanelCols;
  CachedFloats bt, last;
  if (tb) {
    bt = transposed_panels(B, ldb, N, K, panels * kPanelCols);
    B = bt.get();
    ldb = panels * kPanelCols;
  } else if (tail < kPanelCols) {
    last = cached_floats(K * kPanelCols);
    const int64_t c0 = (panels - 1) * kPanelCols;
    for (int64_t k = 0; k < K; ++k) {
      float* dst = last.get() + k * kPanelCols;
      std::copy(B + k * ldb + c0, B + k * ldb + N, dst);
      std::fill(dst + tail, dst + kPanelCols, 0.0f);
    }
  }
  const int64_t row_blocks = (M + kPackedRows - 1) / kPackedRows;
  // Work per task: kPackedRows · 48 · K multiply-adds; at least ~1 M per chunk of tasks.
  const int64_t grain = std::max<int64_t>(1, (int64_t{1} << 20) / std::max<int64_t>(kPackedRows * kPanelCols * K, 1));
  parallel_for(row_blocks * panels, grain, [&](int64_t t0, int64_t t1) {
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t r0 = (t / panels) * kPackedRows, p = t % panels, rows = std::min(kPackedRows, M - r0);
      const int64_t n = std::min(kPanelCols, N - p * kPanelCols);
      const bool padded = !tb && n < kPanelCols;
      gemm_panel(a.data() + r0 * K, rows, K, padded ? last.get() : B + p * kPanelCols, n, nullptr,
                 C + r0 * ldc + p * kPanelCols, ldc, padded ? kPanelCols : ldb);
    }
  });
}

// Whether packed_gemm serves this call: float, plain C = op(A)·op(B), A and a transposed B
// contiguous-rowed as the packing reads them, and enough work to pay for the packing.
bool use_packed(bool ta, bool tb, int64_t M, int64_t N, int64_t K, double alpha, int64_t lda, double beta) {
  return alpha == 1.0 && beta == 0.0 && lda == (ta ? M : K) && M >= kBlockRows && K >= 16 &&
         M * N * K >= (int64_t{1} << 18) && gemm_kernel_available();
}
}  // namespace

template <class T>
void gemm(bool ta, bool tb, int64_t M, int64_t N, int64_t K, T alpha, const T* A, int64_t lda, const T* B,
          int64_t ldb, T beta, T* C, int64_t ldc) {
  if (M == 0 || N == 0) return;
  if constexpr (std::is_same_v<T, float>) {
    if (use_packed(ta, tb, M, N, K, alpha, lda, beta)) {
      packed_gemm(ta, tb, M, N, K, A, B, ldb, C, ldc);
      return;
    }
  }
  const bool split_rows = M >= N;
  const int64_t extent = split_rows ? M : N;
  const int64_t panels = (extent + kPanel - 1) / kPanel;
  parallel_for(panels, 1, [&](int64_t p0, int64_t p1) {
    for (int64_t p = p0; p < p1; ++p) {
      const int64_t s = p * kPanel, n = std::min(kPanel, extent - s);
      if (split_rows) {
        const T* Ap = ta ? A + s : A + s * lda;
        gemm_serial<T>(ta, tb, n, N, K, alpha, Ap, lda, B, ldb, beta, C + s * ldc, ldc);
      } else {
        const T* Bp = tb ? B + s * ldb : B + s;
        gemm_serial<T>(ta, tb, M, n, K, alpha, A, lda, Bp, ldb, beta, C + s, ldc);
      }
    }
  });
}

template void gemm<float>(bool, bool, int64_t, int64_t, int64_t, float, const float*, int64_t, const float*,
                          int64_t, float, float*, int64_t);
template void gemm<double>(bool, bool, int64_t, int64_t, int64_t, double, const double*, int64_t, const double*,
                           int64_t, double, double*, int64_t);

}  // namespace detail

namespace {

// C[b] = op(A[b]) · op(B[b]) for contiguous batches; a batch stride of 0 shares an operand.
void batched_gemm(bool ta, bool tb, int64_t batch, int64_t M, int64_t N, int64_t K, const Tensor& A,
                  int64_t a_batch_stride, const Tensor& B, int64_t b_batch_stride, const Tensor& C) {
  SL_DISPATCH_FLOAT(C.dtype(), "matmul", [&] {
    using T = scalar_t;
    const T* pa = A.data<T>();
    const T* pb = B.data<T>();
    T* pc = C.data<T>();
    const int64_t lda = ta ? M : K, ldb = tb ? K : N;
    if (batch == 1) {
      detail::gemm<T>(ta, tb, M, N, K, T(1), pa, lda, pb, ldb, T(0), pc, N);
      return;
    }
    parallel_for(batch, 1, [&](int64_t b0, int64_t b1) {
      for (int64_t b = b0; b < b1; ++b)
        detail::gemm<T>(ta, tb, M, N, K, T(1), pa + b * a_batch_stride, lda, pb + b * b_batch_stride, ldb, T(0),
                        pc + b * M * N, N);
    });
  });
}

}  // namespace

Tensor matmul(const Tensor& a, const Tensor& b) {
  SL_CHECK(a.dim() >= 2 && b.dim() >= 2, "matmul: needs matrices, got ", a.describe(), " and ", b.describe());
  SL_CHECK(a.dtype() == b.dtype(), "matmul: dtypes differ: ", a.describe(), " and ", b.describe());
  const int64_t M = a.size(-2), K = a.size(-1), N = b.size(-1);
  SL_CHECK(b.size(-2) == K, "matmul: inner dims differ: ", a.describe(), " @ ", b.describe());
  const Shape a_batch(a.shape().begin(), a.shape().end() - 2);
  const Shape b_batch(b.shape().begin(), b.shape().end() - 2);
  Shape out_batch = broadcast_shapes("matmul", a_batch, b_batch);
  Shape out_shape = out_batch;
  out_shape.push_back(M);
  out_shape.push_back(N);
  const int64_t batch = shape_numel(out_batch);

  Tensor A, B;  // contiguous [batch, M, K] (or shared) and [batch, K, N] (or shared)
  int64_t a_stride = M * K, b_stride = K * N;
  {
    NoGradGuard no_grad;
    auto expanded = [&](const Tensor& t, int64_t rows, int64_t cols, int64_t& stride) {
      if (shape_numel(Shape(t.shape().begin(), t.shape().end() - 2)) == 1) {
        stride = 0;  // one matrix shared by every batch
        return reshape(t.detach(), {rows, cols});
      }
      Shape full = out_batch;
      full.push_back(rows);
      full.push_back(cols);
      return expand(t.detach(), full).contiguous();
    };
    A = expanded(a, M, K, a_stride);
    B = expanded(b, K, N, b_stride);
  }
  Tensor y = Tensor::empty(out_shape, a.dtype());
  if (a_stride == 0 && b_stride == 0) {
    batched_gemm(false, false, 1, M, N, K, A, 0, B, 0, y);  // no batch dims (or all size 1)
  } else {
    batched_gemm(false, false, batch, M, N, K, A, a_stride, B, b_stride, y);
  }
  if (needs_grad({a, b})) {
    const bool ga = a.requires_grad(), gb = b.requires_grad();
    const Shape sa = a.shape(), sb = b.shape();
    record("matmul", {a, b}, {y}, [=](const TensorList& g) {
      const Tensor G = g[0].contiguous();
      TensorList r(2);
      if (ga) {  // dA = G · Bᵀ
        Shape s = out_batch;
        s.push_back(M);
        s.push_back(K);
        Tensor dA = Tensor::empty(s, G.dtype());
        batched_gemm(false, true, batch, M, K, N, G, M * N, B, b_stride, dA);
        r[0] = sum_to(dA, sa);
      }
      if (gb) {  // dB = Aᵀ · G, summed over batches that share B
        if (b_stride == 0) {
          Tensor dB = Tensor::zeros({K, N}, G.dtype());
          if (a_stride != 0) {  // A is [batch·M, K] contiguous: one GEMM over all rows
            batched_gemm(true, false, 1, K, N, batch * M, A, 0, G, 0, dB);
          } else {
            Shape s = out_batch;
            s.push_back(K);
            s.push_back(N);
            Tensor per = Tensor::empty(s, G.dtype());
            batched_gemm(true, false, batch, K, N, M, A, 0, G, M * N, per);
            dB = reshape(sum(reshape(per, {batch, K, N}), {0}), {K, N});
          }
          r[1] = reshape(dB, sb);
        } else {
          Shape s = out_batch;
          s.push_back(K);
          s.push_back(N);
          Tensor dB = Tensor::empty(s, G.dtype());
          batched_gemm(true, false, batch, K, N, M, A, a_stride, G, M * N, dB);
          r[1] = sum_to(dB, sb);
        }
      }
      return r;
    });
  }
  return y;
}

}  // namespace sl
