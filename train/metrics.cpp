// Evaluation metrics (Sec 4.2). See metrics.h.
#include "train/metrics.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "util/error.h"
#include "util/math.h"

namespace sl::train {

double angular_error_deg(const glm::dvec3& a, const glm::dvec3& b) {
  const double la = glm::length(a), lb = glm::length(b);
  if (!(la > 0) || !(lb > 0)) return 180.0;
  const double c = std::clamp(glm::dot(a, b) / (la * lb), -1.0, 1.0);
  return std::acos(c) * 180.0 / kPi;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double mean_of(const std::vector<double>& v) {
  return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

PsnrScores masked_psnr(const Tensor& pred, const Tensor& target, const std::vector<char>& mask) {
  SL_CHECK(pred.shape() == target.shape(), "psnr: pred ", pred.describe(), " vs target ", target.describe());
  const Tensor p = pred.detach().to(DType::F64).contiguous(), t = target.detach().to(DType::F64).contiguous();
  const int64_t n = mask.empty() ? p.numel() : static_cast<int64_t>(mask.size());
  SL_CHECK(mask.empty() || (p.dim() == 3 && p.size(1) * p.size(2) == n), "psnr: a mask of ", mask.size(),
           " pixels does not fit the image ", p.describe());
  const int64_t c = n > 0 ? p.numel() / n : 0;
  const double *pp = p.data<double>(), *tp = t.data<double>();
  double pt = 0, pp2 = 0, err = 0, cnt = 0;
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < n; ++i) {
      if (!mask.empty() && !mask[i]) continue;
      const double a = pp[ch * n + i], b = tp[ch * n + i];
      pt += a * b, pp2 += a * a, err += (a - b) * (a - b), cnt += 1;
    }
  PsnrScores r;
  r.valid = cnt > 0;
  const double s = pp2 > 0 ? pt / pp2 : 1.0;  // the least-squares scale of si-PSNR
  double serr = 0;
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < n; ++i) {
      if (!mask.empty() && !mask[i]) continue;
      const double d = s * pp[ch * n + i] - tp[ch * n + i];
      serr += d * d;
    }
  cnt = std::max(cnt, 1.0);
  r.psnr = 10 * std::log10(1.0 / std::max(err / cnt, 1e-10));
  r.si_psnr = 10 * std::log10(1.0 / std::max(serr / cnt, 1e-10));
  return r;
}

double psnr(const Tensor& pred, const Tensor& target) { return masked_psnr(pred, target, {}).psnr; }

double si_psnr(const Tensor& pred, const Tensor& target) { return masked_psnr(pred, target, {}).si_psnr; }

}  // namespace sl::train
