// Matrix products on Eigen's GEMM.
//
// Contract: matmul(a, b) with a [..., M, K] and b [..., K, N] gives [..., M, N]. Batch dims
// broadcast; a 2-d b is shared by every batch of a. Same floating dtype on both sides.
// Work is split in fixed panels (never by thread count), each panel a single-threaded GEMM,
// so results are bitwise identical for any OMP_NUM_THREADS.
#pragma once
#include "autodiff/tensor.h"

namespace sl {

Tensor matmul(const Tensor& a, const Tensor& b);

namespace detail {
// C[M,N] = alpha · op(A) · op(B) + beta · C, row-major with leading dims. op = transpose if flag.
template <class T>
void gemm(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
          int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc);
}  // namespace detail

}  // namespace sl
