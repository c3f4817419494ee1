// streetlight-bench eq1-spacing: error against time of Eq. 1's sample spacing (metric against
// grid, render/radiance_query.h) on the lighting a model predicts for a real photo.
//
// The discrete Eq. 1 composites one α per sample, so the exact value of a nearest-voxel volume is
// the one that composites each voxel the ray crosses exactly once. The reference here marches
// every ray in 20000 steps and composites a voxel when the ray enters it (double precision), then
// adds τ_K L_env. Each row queries the same rays with K samples and one spacing, and reports the
// relative RMSE of the radiance against that reference, the mean |τ_K − τ_ref|, and the best of 3
// wall times.
// Rays: light rays as insertion casts them — origins on and above the ground 5-15 m in front of
// the camera, directions uniform over the upper hemisphere (the sun included).
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "render/environment_map.h"
#include "render/radiance_query.h"
#include "render/spherical_gaussian.h"
#include "tools/bench/bench.h"
#include "tools/bench/kitti_frame.h"
#include "tools/bench/timing.h"
#include "tools/common/cli.h"
#include "train/inference.h"
#include "train/photo_input.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

using sl::render::env_lookup;
using sl::render::radiance_query;
using sl::render::RadianceQueryOptions;
using sl::render::RadianceQueryResult;
using sl::render::sample_spacing_name;
using sl::render::SampleSpacing;
using sl::render::VsgGrid;

namespace sl::bench {
namespace {

struct Reference {
  std::vector<double> radiance, tau;  // [R, 3], [R]
};

// One composite per voxel crossed (nearest lookup), marched finely; the sky term as in Eq. 1.
Reference exact_voxel_march(const Tensor& vsg, const Tensor& env, const Tensor& origins, const Tensor& dirs,
                            const VsgGrid& grid) {
  const Tensor v = vsg.to(DType::F64).contiguous();
  const int64_t X = grid.dims[0], Y = grid.dims[1], Z = grid.dims[2], vox = X * Y * Z, R = origins.size(0);
  const double* p = v.data<double>();
  const Tensor o64 = origins.to(DType::F64).contiguous(), d64 = dirs.to(DType::F64).contiguous();
  const Tensor sky = env_lookup(env.to(DType::F64), d64);
  Reference ref;
  ref.radiance.assign(3 * R, 0.0);
  ref.tau.assign(R, 1.0);
  constexpr int kSteps = 20000;
  for (int64_t r = 0; r < R; ++r) {
    const glm::dvec3 o(o64.data<double>()[3 * r], o64.data<double>()[3 * r + 1], o64.data<double>()[3 * r + 2]);
    const glm::dvec3 d = glm::normalize(
        glm::dvec3(d64.data<double>()[3 * r], d64.data<double>()[3 * r + 1], d64.data<double>()[3 * r + 2]));
    double t0, t1, tau = 1.0, out[3] = {0, 0, 0};
    if (grid.clip_ray(o, d, t0, t1)) {
      int64_t last = -1;
      const double view[3] = {-d.x, -d.y, -d.z};
      for (int s = 0; s < kSteps; ++s) {
        const glm::dvec3 q = grid.to_voxel(o + (t0 + (s + 0.5) * (t1 - t0) / kSteps) * d);
        int64_t i[3];
        for (int a = 0; a < 3; ++a) i[a] = std::clamp<int64_t>(int64_t(std::floor(q[a])), 0, grid.dims[a] - 1);
        const int64_t idx = (i[0] * Y + i[1]) * Z + i[2];
        if (idx == last) continue;
        last = idx;
        const double alpha = p[7 * vox + idx];
        render::sg::Lobe<double> lobe;
        for (int c = 0; c < 3; ++c) lobe.c[c] = p[c * vox + idx], lobe.mu[c] = p[(3 + c) * vox + idx];
        lobe.sharpness = p[6 * vox + idx];
        const auto e = render::sg::eval(lobe, view);
        for (int c = 0; c < 3; ++c) out[c] += tau * alpha * e.value[c];
        tau *= 1.0 - alpha;
      }
    }
    for (int c = 0; c < 3; ++c) ref.radiance[3 * r + c] = out[c] + tau * sky.data<double>()[3 * r + c];
    ref.tau[r] = tau;
  }
  return ref;
}

int run_eq1_spacing(const std::vector<std::string>& args) {
  std::string checkpoint = cli::released_model_path();
  std::string kitti = "../shared/data/street/kitti_000008";
  int64_t rays = 4096;
  bool json = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      SL_CHECK(i + 1 < args.size(), "eq1-spacing: ", a, " needs a value");
      return args[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench eq1-spacing [--checkpoint CKPT] [--kitti DIR] [--rays N] [--json]\n\n"
          "Error against time of Eq. 1's sample spacing (model.volume.spacing: metric or grid) for K = 16..128,\n"
          "against an exact one-composite-per-voxel march, on the lighting CKPT (default: the released model)\n"
          "predicts for the KITTI frame in DIR (default ../shared/data/street/kitti_000008: 000008.png,\n"
          "000008.txt, 000008_calib.json, 000008_velodyne.bin). Rays: N light rays from the ground 5-15 m ahead, upper hemisphere.\n");
      return 0;
    } else if (a == "--checkpoint") {
      checkpoint = value();
    } else if (a == "--kitti") {
      kitti = value();
    } else if (a == "--rays") {
      const std::string s = value();
      rays = std::atoll(s.c_str());
      SL_CHECK(rays >= 1 && rays <= 10000000, "eq1-spacing: --rays must be an integer in [1, 1e7], got '", s, "'");
    } else if (a == "--json") {
      json = true;
    } else {
      fail("eq1-spacing: unknown argument '", a, "' (try eq1-spacing --help)");
    }
  }
  const train::Photo photo = train::load_photo(kitti_000008(kitti));
  train::LightingEstimator est(checkpoint);
  const train::EstimatedLighting l = est.estimate({{photo.ldr, photo.depth, photo.camera}});
  SL_CHECK(l.vsg.defined(), "eq1-spacing: '", checkpoint, "' has no volume branch");

  // Light rays in the canonical frame (the camera looks down −z there).
  Rng rng(7);
  std::vector<double> o(3 * rays), d(3 * rays);
  const glm::dvec3 cam = l.camera.position();
  for (int64_t r = 0; r < rays; ++r) {
    o[3 * r] = cam.x + rng.uniform(-3.0, 3.0);
    o[3 * r + 1] = rng.uniform(0.1, 2.0);
    o[3 * r + 2] = cam.z - rng.uniform(5.0, 15.0);
    const double z = rng.uniform(0.0, 1.0), phi = rng.uniform(0.0, kTwoPi), s = std::sqrt(1.0 - z * z);
    d[3 * r] = s * std::cos(phi), d[3 * r + 1] = z, d[3 * r + 2] = s * std::sin(phi);
  }
  const Tensor origins = Tensor::from_vector(o, {rays, 3}).to(DType::F32);
  const Tensor dirs = Tensor::from_vector(d, {rays, 3}).to(DType::F32);
  const Reference ref = exact_voxel_march(l.vsg, l.env, origins, dirs, l.grid);
  double ref2 = 0;
  for (double x : ref.radiance) ref2 += x * x;
  const double ref_rms = std::sqrt(ref2 / double(ref.radiance.size()));

  if (!json) std::printf("%-7s %5s %10s %12s %10s\n", "spacing", "K", "rel_rmse", "mean|dtau|", "ms");
  for (int K : {16, 32, 64, 128})
    for (SampleSpacing sp : {SampleSpacing::kMetric, SampleSpacing::kGrid}) {
      RadianceQueryOptions q = est.volume_query();
      q.samples = K;
      q.spacing = sp;
      RadianceQueryResult res;
      const double ms = best_ms([&] { res = radiance_query(l.vsg, l.env, origins, dirs, l.grid, q); }, 3, 1);
      const Tensor rad = res.radiance.to(DType::F64).contiguous(), tau = res.transmittance.to(DType::F64).contiguous();
      double e2 = 0, dt = 0;
      for (size_t i = 0; i < ref.radiance.size(); ++i) {
        const double e = rad.data<double>()[i] - ref.radiance[i];
        e2 += e * e;
      }
      for (int64_t r = 0; r < rays; ++r) dt += std::abs(tau.data<double>()[r] - ref.tau[r]);
      const double rel = std::sqrt(e2 / double(ref.radiance.size())) / std::max(ref_rms, 1e-30);
      if (json)
        std::printf("{\"bench\": \"eq1_spacing\", \"spacing\": \"%s\", \"K\": %d, \"rays\": %lld, \"rel_rmse\": %.5f, "
                    "\"mean_abs_dtau\": %.5f, \"ms\": %.2f}\n",
                    sample_spacing_name(sp), K, (long long)rays, rel, dt / double(rays), ms);
      else
        std::printf("%-7s %5d %10.4f %12.4f %10.2f\n", sample_spacing_name(sp), K, rel, dt / double(rays), ms);
    }
  return 0;
}

Registrar reg("eq1-spacing", "Eq. 1 sample spacing (metric vs grid): error against time", &run_eq1_spacing);

}  // namespace
}  // namespace sl::bench
