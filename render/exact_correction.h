// The choice of rays for the exact corrections of the radiance cache (render/object_insertion.h,
// "Exact corrections"): which M of a sample's n rays are also marched exactly, and the weight
// that keeps Σ_k w_k·(L_exact − L_cached)_k unbiased when only those are marched.
//
// Ray k is drawn with probability p_k = (1 − β)/n + β·s_k/Σs, s_k ≥ 0 its score (the cached
// contribution |w_k·L_k|: the cache's error is roughly proportional to the light it reads, so
// the rays that carry light are corrected most often), β = kScoreShare; M draws at the
// stratified points (j + u)/M of the inverse CDF. Then Σ_k d_k ≈ (1/M) Σ_j d_{k_j}/p_{k_j} is
// unbiased for any d, and its variance is smallest when p_k ∝ |d_k|.
//
// Requires: n ≥ 1, 1 ≤ M ≤ kMaxCorrections, u in [0, 1); a non-finite or negative score counts
//   as 0. Guarantees: returns the number of picks written: M ≥ n picks every ray once with
//   weight 1 (the corrected sum is then the exact sum); otherwise M picks (an index may repeat),
//   weight = 1/(M·p_k) > 0, uniform (weight n/M) when every score is 0. Deterministic.
//   Internal to render/.
#pragma once
#include <algorithm>
#include <cmath>

namespace sl::render::insertion {

inline constexpr float kScoreShare = 0.75f;  // β: the rest is uniform, so no ray has p_k = 0
inline constexpr int kMaxCorrections = 64;     // M per sample, at most

struct CorrectionPick {
  int index = 0;
  float weight = 0.0f;  // 1/(M·p_index)
};

inline int pick_corrections(const float* score, int n, int M, float u, CorrectionPick* out) {
  if (M >= n) {  // every ray, once: the corrected sum is the exact one
    for (int k = 0; k < n; ++k) out[k] = {k, 1.0f};
    return n;
  }
  double total = 0;
  for (int k = 0; k < n; ++k) total += std::isfinite(score[k]) && score[k] > 0 ? score[k] : 0.0;
  const double beta = total > 0 ? kScoreShare : 0.0;
  auto p_of = [&](int k) {
    const double s = std::isfinite(score[k]) && score[k] > 0 ? score[k] : 0.0;
    return (1.0 - beta) / n + (beta > 0 ? beta * s / total : 0.0);
  };
  int k = 0;
  double cdf = p_of(0);
  for (int j = 0; j < M; ++j) {
    const double target = (j + double(u)) / M;
    while (k < n - 1 && cdf <= target) cdf += p_of(++k);
    out[j].index = k;
    out[j].weight = float(1.0 / (M * p_of(k)));
  }
  return M;
}

}  // namespace sl::render::insertion
