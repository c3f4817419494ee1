// Strided iteration over N-d index spaces (internal to autodiff kernels).
//
// Contract: for_each_strided(shape, {strides...}, body) calls body(offsets..., count, steps...)
// once per innermost row: offsets are the element offsets of the row's first element in each
// operand, count the row length and steps each operand's innermost stride. Adjacent dims that
// are contiguous in every operand are merged first, so dense operands become one long row.
// Rows are distributed over threads; rows never overlap in the output, so results do not
// depend on the thread count.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "autodiff/tensor.h"
#include "util/parallel.h"

namespace sl::detail {

template <size_t K>
struct StridedPlan {
  Shape shape;                    // merged shape
  std::array<Shape, K> strides;   // merged strides, one per operand
};

template <size_t K>
StridedPlan<K> plan_strided(const Shape& shape, const std::array<Shape, K>& strides) {
  StridedPlan<K> plan;
  for (size_t d = 0; d < shape.size(); ++d) {
    if (shape[d] == 1) continue;  // size-1 dims never move any operand
    bool merge = !plan.shape.empty();
    for (size_t k = 0; k < K && merge; ++k)
      merge = plan.strides[k].back() == strides[k][d] * shape[d];
    if (merge) {
      plan.shape.back() *= shape[d];
      for (size_t k = 0; k < K; ++k) plan.strides[k].back() = strides[k][d];
    } else {
      plan.shape.push_back(shape[d]);
      for (size_t k = 0; k < K; ++k) plan.strides[k].push_back(strides[k][d]);
    }
  }
  if (plan.shape.empty()) {
    plan.shape.push_back(1);
    for (size_t k = 0; k < K; ++k) plan.strides[k].push_back(0);
  }
  return plan;
}

// body(const std::array<int64_t,K>& offsets, int64_t count, const std::array<int64_t,K>& steps)
template <size_t K, class Body>
void for_each_strided(const Shape& shape, const std::array<Shape, K>& strides, Body&& body,
                      int64_t grain_elements = 32768) {
  if (shape_numel(shape) == 0) return;
  const StridedPlan<K> plan = plan_strided<K>(shape, strides);
  const size_t nd = plan.shape.size();
  const int64_t inner = plan.shape[nd - 1];
  int64_t rows = 1;
  for (size_t d = 0; d + 1 < nd; ++d) rows *= plan.shape[d];
  std::array<int64_t, K> steps;
  for (size_t k = 0; k < K; ++k) steps[k] = plan.strides[k][nd - 1];
  // Long rows are cut into fixed pieces so that one dense operand still spreads over threads.
  const int64_t piece = std::min<int64_t>(inner, std::max<int64_t>(grain_elements, 1));
  const int64_t pieces_per_row = (inner + piece - 1) / piece;
  const int64_t grain_items = std::max<int64_t>(1, grain_elements / piece);
  parallel_for(rows * pieces_per_row, grain_items, [&](int64_t i0, int64_t i1) {
    for (int64_t item = i0; item < i1; ++item) {
      const int64_t r = item / pieces_per_row, p = item % pieces_per_row;
      std::array<int64_t, K> off{};
      int64_t rem = r;
      for (size_t d = nd - 1; d-- > 0;) {
        const int64_t i = rem % plan.shape[d];
        rem /= plan.shape[d];
        for (size_t k = 0; k < K; ++k) off[k] += i * plan.strides[k][d];
      }
      const int64_t start = p * piece;
      for (size_t k = 0; k < K; ++k) off[k] += start * steps[k];
      body(off, std::min(piece, inner - start), steps);
    }
  });
}

}  // namespace sl::detail
