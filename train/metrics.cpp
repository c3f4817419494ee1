// Evaluation metrics (Sec 4.2). See metrics.h.
#include "train/metrics.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace sl::train {

double angular_error_deg(const glm::dvec3& a, const glm::dvec3& b) {
  const double la = glm::length(a), lb = glm::length(b);
  if (!(la > 0) || !(lb > 0)) return 180.0;
  const double c = std::clamp(glm::dot(a, b) / (la * lb), -1.0, 1.0);
  return std::acos(c) * 180.0 / 3.14159265358979323846;
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

namespace {

double psnr_scaled(const std::vector<double>& p, const std::vector<double>& t, double s) {
  double se = 0;
  for (size_t i = 0; i < p.size(); ++i) se += (s * p[i] - t[i]) * (s * p[i] - t[i]);
  const double mse = std::max(se / static_cast<double>(std::max<size_t>(p.size(), 1)), 1e-10);
  return 10.0 * std::log10(1.0 / mse);
}

}  // namespace

double psnr(const Tensor& pred, const Tensor& target) {
  SL_CHECK(pred.shape() == target.shape(), "psnr: pred ", pred.describe(), " vs target ", target.describe());
  return psnr_scaled(pred.to_vector(), target.to_vector(), 1.0);
}

double si_psnr(const Tensor& pred, const Tensor& target) {
  SL_CHECK(pred.shape() == target.shape(), "si_psnr: pred ", pred.describe(), " vs target ", target.describe());
  const auto p = pred.to_vector(), t = target.to_vector();
  double pt = 0, pp = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    pt += p[i] * t[i];
    pp += p[i] * p[i];
  }
  return psnr_scaled(p, t, pp > 0 ? pt / pp : 1.0);
}

}  // namespace sl::train
