#include "render/progressive_render.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "render/exposure.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::render {
namespace {

// acc = (acc·n_acc + pass·n_pass) / (n_acc + n_pass), in place.
void accumulate(Tensor& acc, int64_t n_acc, const Tensor& pass, int64_t n_pass) {
  if (n_acc == 0) {
    acc = pass.contiguous().clone();
    return;
  }
  SL_CHECK(acc.shape() == pass.shape(), "render_progressive: a pass returned ", pass.describe(), ", expected ",
           acc.describe());
  const Tensor p = pass.contiguous();
  float* a = acc.data<float>();
  const float* b = p.data<float>();
  const double wa = double(n_acc) / double(n_acc + n_pass), wb = 1.0 - wa;
  for (int64_t i = 0; i < acc.numel(); ++i) a[i] = float(wa * a[i] + wb * b[i]);
}

}  // namespace

double ldr_noise(const Tensor& a, const Tensor& b, double exposure) {
  SL_CHECK(a.shape() == b.shape(), "ldr_noise: shapes differ: ", a.describe(), " and ", b.describe());
  const Tensor ca = a.contiguous(), cb = b.contiguous();
  const float *pa = ca.data<float>(), *pb = cb.data<float>();
  double s = 0.0;
  for (int64_t i = 0; i < ca.numel(); ++i) {
    const double d = 0.5 * (ldr_encode(pa[i], exposure) - ldr_encode(pb[i], exposure));
    s += d * d;
  }
  return ca.numel() > 0 ? std::sqrt(s / double(ca.numel())) : 0.0;
}

ProgressiveResult render_progressive(const RenderPass& pass, const ProgressiveOptions& o,
                                     const std::function<void(const ProgressiveStatus&)>& on_pass) {
  const int seeds = o.two_seeds ? 2 : 1;
  SL_CHECK(o.max_spp >= seeds, "render_progressive: max_spp must be >= ", seeds, ", got ", o.max_spp);
  SL_CHECK(o.seconds >= 0.0 && std::isfinite(o.seconds), "render_progressive: seconds must be >= 0, got ", o.seconds);
  SL_CHECK(o.target_noise >= 0.0 && std::isfinite(o.target_noise),
           "render_progressive: target_noise must be >= 0, got ", o.target_noise);
  SL_CHECK(o.target_noise == 0.0 || o.two_seeds, "render_progressive: a noise target needs two_seeds");
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const uint64_t seed_of[2] = {o.seed, mix64(o.seed ^ 0x2b992ddfa23249d6ULL)};
  const int64_t per_seed_max = o.max_spp / seeds;

  Tensor half[2];
  int64_t per_seed = 0;  // samples per pixel per seed so far
  ProgressiveResult result;
  ProgressiveStatus& st = result.status;
  st.max_spp = int(per_seed_max * seeds);
  while (per_seed < per_seed_max) {
    const bool one_pass = o.single_pass_without_budget && o.seconds == 0.0 && o.target_noise == 0.0;
    const int64_t n = one_pass ? per_seed_max : std::min<int64_t>(std::max<int64_t>(per_seed, 1), per_seed_max - per_seed);
    if (per_seed > 0 && o.seconds > 0.0) {
      // Passes double, so the next one costs about as much as everything so far.
      const double predicted = elapsed() * double(per_seed + n) / double(per_seed);
      if (predicted > o.seconds) break;
    }
    for (int k = 0; k < seeds; ++k) accumulate(half[k], per_seed, pass(seed_of[k], per_seed, int(n)), n);
    per_seed += n;
    st.spp = int(per_seed * seeds);
    st.seconds = elapsed();
    if (o.two_seeds) {
      Tensor mean = half[0].clone();
      accumulate(mean, 1, half[1], 1);
      const double e = o.exposure > 0.0 ? o.exposure : exposure_for_ldr_median(mean, o.auto_median_ldr);
      st.noise = ldr_noise(half[0], half[1], e);
    }
    if (on_pass) on_pass(st);
    if (o.target_noise > 0.0 && st.noise <= o.target_noise) break;
  }
  result.radiance = half[0];
  if (o.two_seeds) accumulate(result.radiance, 1, half[1], 1);
  return result;
}

}  // namespace sl::render
