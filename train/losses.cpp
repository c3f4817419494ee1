// Training losses (Sec 3.4). See losses.h for the contract of each.
#include "train/losses.h"

#include <cmath>

#include "autodiff/ops.h"
#include "util/math.h"

namespace sl::train {

Tensor log_encoded_l2(const Tensor& pred, const Tensor& target) {
  SL_CHECK(pred.shape() == target.shape(), "log_encoded_l2: pred ", pred.describe(), " vs target ", target.describe());
  return mean(square(sub(log1p(relu(pred)), log1p(relu(target)))));
}

Tensor log_encoded_l2_from_log(const Tensor& log_pred, const Tensor& target) {
  SL_CHECK(log_pred.shape() == target.shape(), "log_encoded_l2_from_log: pred ", log_pred.describe(), " vs target ",
           target.describe());
  return mean(square(sub(softplus(log_pred), log1p(relu(target)))));
}

Tensor log_encoded_range_l2_from_log(const Tensor& log_pred, double lo, double hi) {
  SL_CHECK(lo >= 0 && lo <= hi && std::isfinite(hi), "log_encoded_range_l2_from_log: need 0 <= lo <= hi < inf, got [",
           lo, ", ", hi, "]");
  const Tensor u = softplus(log_pred);
  const Tensor below = relu(neg(add_scalar(u, -std::log1p(lo))));  // log(1 + lo) − u where positive
  const Tensor above = relu(add_scalar(u, -std::log1p(hi)));
  return mean(square(add(below, above)));
}

Tensor angular_l1(const Tensor& pred_dir, const Tensor& target_dir) {
  SL_CHECK(pred_dir.dim() == 2 && pred_dir.size(1) == 3 && pred_dir.shape() == target_dir.shape(),
           "angular_l1: expected two [N, 3] direction tensors, got ", pred_dir.describe(), " and ", target_dir.describe());
  const Tensor cosine = sum(mul(normalize(pred_dir, 1, 1e-8), normalize(target_dir, 1, 1e-8)), {1});
  return mean(acos(clamp(cosine, -1.0, 1.0)));
}

Tensor elevation_azimuth_l1(const Tensor& pred_dir, const Tensor& target_dir) {
  SL_CHECK(pred_dir.dim() == 2 && pred_dir.size(1) == 3 && pred_dir.shape() == target_dir.shape(),
           "elevation_azimuth_l1: expected two [N, 3] direction tensors, got ", pred_dir.describe(), " and ",
           target_dir.describe());
  const Tensor t = target_dir.detach();
  auto column = [](const Tensor& d, int64_t k) { return select(d, 1, k); };
  auto elevation = [&](const Tensor& d) {
    const Tensor x = column(d, 0), z = column(d, 2);
    return atan2(column(d, 1), sqrt(add_scalar(add(square(x), square(z)), 1e-12)));
  };
  const Tensor elev_t = elevation(t);
  const Tensor d_elev = abs(sub(elevation(pred_dir), elev_t));
  // Wrapped azimuth difference of the horizontal parts (x, z): atan2(cross, dot), scale-free.
  const Tensor px = column(pred_dir, 0), pz = column(pred_dir, 2), tx = column(t, 0), tz = column(t, 2);
  const Tensor cross = sub(mul(px, tz), mul(pz, tx)), dot = add(mul(px, tx), mul(pz, tz));
  const Tensor d_azim = mul(abs(atan2(cross, dot)), cos(elev_t));
  return mean(add(d_elev, d_azim));
}

Tensor l1(const Tensor& pred, const Tensor& target) {
  SL_CHECK(pred.shape() == target.shape(), "l1: pred ", pred.describe(), " vs target ", target.describe());
  return mean(abs(sub(pred, target)));
}

Tensor masked_l1(const Tensor& pred, const Tensor& target, const Tensor& mask) {
  SL_CHECK(pred.shape() == target.shape(), "masked_l1: pred ", pred.describe(), " vs target ", target.describe());
  const Tensor m = expand(mask, pred.shape());
  const double count = sum(m.detach()).item();
  return mul_scalar(sum(mul(abs(sub(pred, target)), m)), 1.0 / std::max(count, 1.0));
}

Tensor ldr_from_hdr(const Tensor& hdr) {
  return pow_scalar(clamp(hdr, 1e-6, 1.0), 1.0 / kLdrGamma);
}

Tensor radiance_l2(const Tensor& radiance, const Tensor& target_ldr) {
  SL_CHECK(radiance.shape() == target_ldr.shape(), "radiance_l2: radiance ", radiance.describe(), " vs target ",
           target_ldr.describe());
  return mean(square(sub(ldr_from_hdr(radiance), target_ldr)));
}

Tensor depth_consistency(const Tensor& depth, const Tensor& transmittance, const Tensor& target_distance) {
  SL_CHECK(depth.shape() == transmittance.shape() && depth.shape() == target_distance.shape(),
           "depth_consistency: depth ", depth.describe(), ", transmittance ", transmittance.describe(), ", target ",
           target_distance.describe(), " must have one shape");
  // Valid targets: finite and positive; the rest become 0 with weight 0 (no NaN reaches a product).
  const std::vector<double> t = target_distance.to_vector();
  std::vector<double> valid(t.size()), clean(t.size());
  double count = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    const bool ok = std::isfinite(t[i]) && t[i] > 0;
    valid[i] = ok ? 1.0 : 0.0;
    clean[i] = ok ? t[i] : 0.0;
    count += valid[i];
  }
  const Tensor w = Tensor::from_vector(valid, depth.shape(), depth.dtype());
  const Tensor target = Tensor::from_vector(clean, depth.shape(), depth.dtype());
  const Tensor opacity = clamp(rsub_scalar(1.0, transmittance), 1e-3, 1.0);
  const Tensor normalised = div(relu(depth), opacity);
  const Tensor err = abs(sub(log1p(normalised), log1p(target)));
  return mul_scalar(sum(mul(err, w)), 1.0 / std::max(count, 1.0));
}

Tensor sky_separation_bce(const Tensor& transmittance, const Tensor& sky_mask) {
  SL_CHECK(transmittance.shape() == sky_mask.shape(), "sky_separation_bce: transmittance ", transmittance.describe(),
           " vs sky mask ", sky_mask.describe());
  constexpr double eps = 1e-4;
  const Tensor tau = clamp(transmittance, 0.0, 1.0);
  const Tensor pos = mul(sky_mask, log(add_scalar(tau, eps)));
  const Tensor neg = mul(rsub_scalar(1.0, sky_mask), log(add_scalar(rsub_scalar(1.0, tau), eps)));
  return mul_scalar(mean(add(pos, neg)), -1.0);
}

Tensor bce_with_logits(const Tensor& logits, const Tensor& labels) {
  SL_CHECK(logits.shape() == labels.shape(), "bce_with_logits: logits ", logits.describe(), " vs labels ",
           labels.describe());
  return mean(sub(softplus(logits), mul(labels, logits)));
}

Tensor generator_adversarial(const Tensor& d_fake) { return mul_scalar(mean(d_fake), -1.0); }

Tensor discriminator_hinge(const Tensor& d_real, const Tensor& d_fake) {
  return add(mean(relu(rsub_scalar(1.0, d_real))), mean(relu(add_scalar(d_fake, 1.0))));
}

}  // namespace sl::train
