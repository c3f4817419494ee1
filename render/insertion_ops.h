// The two reductions behind object insertion, as one tape node each (used by object_insertion).
//
// weighted_segment_sum (Eq. 2): values [R, 3] (tape), weights [R, 3] (constant), and segment
//   offsets o[0..P] (o[0] = 0, non-decreasing, o[P] = R) give out[p] = Σ_{r ∈ [o_p, o_{p+1})}
//   w_r ⊙ v_r, [P, 3]. The light samples of a pixel are one segment: weights carry the BRDF,
//   cosine, 1/pdf and 1/(samples) factors.
// shadow_ratio (Eq. 4): radiance L [R, 3] (tape), per-ray sample weights w_r = cos/pdf and
//   visibility m_r ∈ {I_a, 1} (constants) and offsets give, per channel, [P, 3]:
//     S[p] = (Σ m_r w_r L_r + ε) / (Σ w_r L_r + ε).
//   With cosine-weighted directions w is constant and cancels (the paper's form). The guard
//   ε > 0 keeps S finite and → 1 as the light vanishes. ∂S/∂L_r = w_r (m_r − S)/(Σ w L + ε).
// Segments are independent, so both are deterministic for any thread count.
#pragma once
#include <vector>

#include "autodiff/tensor.h"

namespace sl::render {

Tensor weighted_segment_sum(const Tensor& values, const Tensor& weights, const std::vector<int64_t>& offsets);
Tensor shadow_ratio(const Tensor& radiance, const std::vector<double>& weights, const std::vector<double>& visibility,
                    const std::vector<int64_t>& offsets, double epsilon);

}  // namespace sl::render
