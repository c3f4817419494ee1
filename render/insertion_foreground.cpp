// Eq. 2: the G-buffer and the light rays of the inserted object (see insertion_foreground.h).
#include "render/insertion_foreground.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "render/exact_correction.h"
#include "render/insertion_denoise.h"
#include "render/insertion_mixture_pdf.h"
#include "render/pixel_window.h"
#include "render/qmc_sampler.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::render::insertion {
namespace {

disney::Params material_at(const Mesh& mesh, const Hit& hit) {
  disney::Params p;
  if (mesh.materials.empty()) return p;
  const uint32_t id = hit.triangle < mesh.material_ids.size() ? mesh.material_ids[hit.triangle] : 0;
  const Material& m = mesh.materials[std::min<size_t>(id, mesh.materials.size() - 1)];
  glm::vec2 uv(0.0f);
  if (!mesh.uvs.empty()) {
    const glm::uvec3 t = mesh.triangles[hit.triangle];
    uv = (1 - hit.u - hit.v) * mesh.uvs[t.x] + hit.u * mesh.uvs[t.y] + hit.v * mesh.uvs[t.z];
  }
  p.base_color = glm::vec3(m.base_color(uv));
  p.metallic = m.metallic;
  p.roughness = m.roughness;
  p.clearcoat = m.clearcoat;
  p.clearcoat_gloss = 1.0f - m.clearcoat_roughness;
  return p;
}

glm::vec3 shading_normal(const Mesh& mesh, const Hit& hit, const glm::vec3& dir) {
  const glm::uvec3 t = mesh.triangles[hit.triangle];
  glm::vec3 n;
  if (mesh.normals.size() == mesh.positions.size())
    n = (1 - hit.u - hit.v) * mesh.normals[t.x] + hit.u * mesh.normals[t.y] + hit.v * mesh.normals[t.z];
  else
    n = glm::cross(mesh.positions[t.y] - mesh.positions[t.x], mesh.positions[t.z] - mesh.positions[t.x]);
  n = safe_normalize(n);
  if (glm::dot(n, n) == 0.0f) n = -dir;
  return glm::dot(n, dir) > 0 ? -n : n;  // face the viewer
}

}  // namespace

// Pass 1: primary rays against the objects, in parallel over image rows.
std::vector<GSample> gbuffer(const InsertionInputs& in, const InsertionOptions& opt, const Mesh& mesh, const Bvh& bvh,
                             const double* depth, Foreground& fg, InsertionStats& stats) {
  const Camera& cam = in.camera;
  const int W = cam.intrinsics().width, H = cam.intrinsics().height;
  const Rect r = screen_bounds(mesh.bounds(), cam, opt.prune);
  stats.image_pixels_total = int64_t(W) * H;
  stats.foreground_pixels_shaded = r.area();
  fg.coverage.assign(size_t(W) * H, 0.0f);
  fg.depth.assign(size_t(W) * H, 0.0f);
  fg.silhouette.assign(size_t(W) * H, 0.0f);
  fg.width = W;
  const uint64_t aa_seed = hash_counter(opt.seed, kTagAa);
  std::vector<std::vector<GSample>> rows(size_t(std::max(0, r.y1 - r.y0)));
  // Dynamic: rows cross the object over different lengths.
  parallel_for_dynamic(int64_t(rows.size()), 1, [&](int64_t b, int64_t e) {
    for (int64_t ri = b; ri < e; ++ri) {
      const int row = r.y0 + int(ri);
      rows[size_t(ri)].reserve(size_t(std::max(0, r.x1 - r.x0)) * size_t(opt.aa_samples));
      for (int col = r.x0; col < r.x1; ++col) {
        const int64_t pix = int64_t(row) * W + col;
        int visible = 0, hits = 0;
        double zsum = 0;
        for (int s = 0; s < opt.aa_samples; ++s) {
          // Owen-scrambled Sobol positions: any 2^m primary samples of a pixel are stratified
          // (2×2, 4×1 and 1×4 for four), which halves the coverage error of silhouette pixels
          // against independent uniform positions, at the same cost and still unbiased.
          const glm::vec2 j = qmc::owen_pair(aa_seed, uint64_t(pix), uint64_t(s), 0);
          const double u = col + double(j.x), v = row + double(j.y);
          const CameraRay cr = cam.ray(u, v);
          Ray ray;
          ray.origin = glm::vec3(cr.origin);
          ray.direction = glm::vec3(cr.direction);
          const Hit hit = bvh.intersect(ray);
          if (!hit.hit()) continue;
          const glm::vec3 x = ray.origin + hit.t * ray.direction;
          const double z = cam.world_to_camera(glm::dvec3(x)).z;
          ++hits;
          // Scene geometry nearer than the object hides it: the photo wins.
          if (valid_depth(depth[pix]) && depth[pix] < z * (1.0 - 1e-3)) continue;
          ++visible;
          zsum += z;
          rows[ri].push_back({pix, uint64_t(pix) * uint64_t(opt.aa_samples) + uint64_t(s), x,
                              shading_normal(mesh, hit, ray.direction), -ray.direction, material_at(mesh, hit)});
        }
        fg.silhouette[pix] = float(hits) / opt.aa_samples;
        if (visible > 0) {
          fg.coverage[pix] = float(visible) / opt.aa_samples;
          fg.depth[pix] = float(zsum / visible);
        }
      }
    }
  });
  // Concatenated in row order, each row copied by one thread into its slot.
  std::vector<size_t> start(rows.size() + 1, 0);
  for (size_t i = 0; i < rows.size(); ++i) start[i + 1] = start[i] + rows[i].size();
  std::vector<GSample> all(start.back());
  parallel_for(int64_t(rows.size()), 1, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      std::copy(rows[size_t(i)].begin(), rows[size_t(i)].end(), all.begin() + std::ptrdiff_t(start[size_t(i)]));
      std::vector<GSample>().swap(rows[size_t(i)]);
    }
  });
  stats.foreground_samples = int64_t(all.size());
  return all;
}

namespace {

// The seed of a family of light samples in pass `pass_tag` (0: the first pass, as before).
uint64_t pass_seed(const InsertionOptions& opt, uint64_t tag, uint64_t pass_tag) {
  return pass_tag == 0 ? sample_seed(opt, tag) : hash_counter(sample_seed(opt, tag), pass_tag);
}

// The N light directions of G-buffer sample i and their weights f·cos/pdf/(N·aa) (× I_a where
// the object blocks them; less c·cos/pdf/(N·aa) with the control variate), into l[0..N), w[0..N).
// A failed sample gets l = n and w = 0 (a harmless ray keeps the layout regular).
// What every sample's light rays share: seeds, the technique split and the normalisation.
struct LightSampling {
  // pass_tag != 0: an independent set (the adaptive pass), its seeds hashed with the tag.
  LightSampling(const InsertionOptions& opt, int n, uint64_t pass_tag = 0)
      : light_seed(pass_seed(opt, kTagLight, pass_tag)), choice_seed(pass_seed(opt, kTagChoice, pass_tag)),
        rot_seed(pass_seed(opt, kTagRotation, pass_tag)), N(n), n_brdf(n / 2), c_brdf(float(n / 2) / float(n)),
        c_env(1.0f - c_brdf), norm(1.0f / float(n * opt.aa_samples)) {}
  uint64_t light_seed, choice_seed, rot_seed;
  int N, n_brdf;  // inference: n_brdf BRDF samples first, then environment samples
  float c_brdf, c_env, norm;
};

// Inference with the bilinear sky sampler: stratified multi-sample MIS of BRDF and sky
// sampling, one stratified set per pixel interleaved over its anti-aliasing samples. The BRDF's
// value and density come with its sample (or from one evaluate()); the panorama coordinates with
// the sky's sample, so the sky's density and the cache's read share them. The sky's directions
// are drawn as one batch, the BRDF's directions' coordinates made as another, then the sky's
// densities of all N rays as a third (lanes: the same bits as one at a time, without a chain of
// divisions and square roots, or an atan2 and an asin, per ray), and `finish` takes each ray in
// order. cos(elevation) and the mixture are rounded per technique as the one-ray-at-a-time code
// rounded them (render/insertion_mixture_pdf.h).
template <class Finish>
void bilinear_light_rays(const LightSampling& sampling, const EnvironmentMap& env_map, const GSample& g,
                         const disney::Point& point, const SplitRotations& rotations, int aa, Finish&& finish) {
  const int N = sampling.N, n_brdf = sampling.n_brdf;
  static thread_local std::vector<SplitSample> splits;
  static thread_local std::vector<float> sky_u1, sky_u2, sky_pe;
  static thread_local std::vector<glm::vec3> ray_l;
  static thread_local std::vector<disney::Sample> ray_b;
  static thread_local std::vector<equirect::UV> ray_unit, sky_unit;
  static thread_local std::vector<double> sky_cos;
  static thread_local std::vector<char> ray_has_unit;
  splits.resize(size_t(N));
  sky_u1.clear(), sky_u2.clear();
  for (int k = 0; k < N; ++k) {
    splits[size_t(k)] = split_sample(rotations, k, N, n_brdf, int(g.stream % uint64_t(aa)), aa);
    if (splits[size_t(k)].technique != 0) sky_u1.push_back(splits[size_t(k)].u.x), sky_u2.push_back(splits[size_t(k)].u.y);
  }
  ray_l.resize(size_t(N)), ray_b.resize(size_t(N)), ray_unit.resize(size_t(N)), ray_has_unit.resize(size_t(N));
  env_map.sample_bilinear_directions(int(sky_u1.size()), sky_u1.data(), sky_u2.data(), ray_l.data() + n_brdf,
                                     ray_unit.data() + n_brdf);
  // The BRDF's draws (the first n_brdf), then their panorama coordinates as one batch.
  for (int k = 0; k < n_brdf; ++k) {
    const SplitSample& sp = splits[size_t(k)];
    ray_b[size_t(k)] = disney::sample(point, sp.u.x, sp.u.y, uniform01f(sampling.choice_seed, g.stream, k + N));
    ray_l[size_t(k)] = ray_b[size_t(k)].wi;
  }
  equirect::directions_to_units(n_brdf, ray_l.data(), ray_unit.data());
  // The densities' inputs, packed for the rays that have panorama coordinates.
  sky_unit.clear(), sky_cos.clear();
  for (int k = 0; k < N; ++k) {
    const SplitSample& sp = splits[size_t(k)];
    const glm::vec3& l = ray_l[size_t(k)];
    bool have_unit = true;
    if (sp.technique == 0) {
      have_unit = glm::dot(l, l) > 0.0f;
    } else {
      ray_b[size_t(k)] = disney::evaluate(point, l);
    }
    ray_has_unit[size_t(k)] = have_unit;
    if (have_unit) {
      sky_unit.push_back(ray_unit[size_t(k)]);
      sky_cos.push_back(sky_cos_elevation(l, sp.technique != 0));
    }
  }
  sky_pe.resize(sky_unit.size());
  env_map.pdf_bilinear_units(int(sky_unit.size()), sky_unit.data(), sky_cos.data(), sky_pe.data());
  size_t next = 0;
  for (int k = 0; k < N; ++k) {
    const bool have_unit = ray_has_unit[size_t(k)] != 0;
    const float pe = have_unit ? sky_pe[next++] : 0.0f;
    const disney::Sample& b = ray_b[size_t(k)];
    const float pdf = mixture_pdf(sampling.c_brdf, b.pdf, sampling.c_env, pe, splits[size_t(k)].technique != 0);
    finish(k, ray_l[size_t(k)], b.f, true, pdf, have_unit ? ray_unit[size_t(k)] : equirect::UV{0.5, 0.5}, have_unit);
  }
}

// cv: the sample's control-variate lobe (disney::diffuse_control), or null without one.
// full, when given, gets each weight before the control variate's term is taken off.
void light_rays(const InsertionOptions& opt, const LightSampling& sampling, const Bvh& bvh, const EnvironmentMap& env_map,
                const GSample& g, const disney::DiffuseControl* cv, glm::vec3* ls, glm::vec3* ws,
                equirect::UV* units, glm::vec3* full = nullptr) {
  const uint64_t light_seed = sampling.light_seed, choice_seed = sampling.choice_seed, rot_seed = sampling.rot_seed;
  const int N = sampling.N, n_brdf = sampling.n_brdf;
  const float c_brdf = sampling.c_brdf, c_env = sampling.c_env, norm = sampling.norm;
  const Frame frame(g.n);
  const glm::vec3 origin = light_origin(g);
  const bool inference = opt.importance_sampling && n_brdf > 0;
  // Inference: the shading point and the stratified set's rotations, once for all N directions.
  const int aa = opt.stratify_per_pixel ? opt.aa_samples : 1;
  const disney::Point point = inference ? disney::point(g.material, g.n, g.wo) : disney::Point{};
  const SplitRotations rotations = inference ? split_rotations(rot_seed, g.stream / uint64_t(aa)) : SplitRotations{};
  // A failed ray's panorama coordinates are the normal's: made once, at the sample's first.
  equirect::UV normal_unit{};
  bool have_normal_unit = false;
  // One light ray's tail: its weight, the self-occlusion test, and the three outputs.
  auto finish = [&](int k, glm::vec3 l, const glm::vec3& f, bool have_f, float pdf, equirect::UV unit,
                    bool have_unit) {
    const float cos_l = glm::dot(l, g.n);
    glm::vec3 w(0.0f);
    if (cos_l > 0 && pdf > 0 && std::isfinite(pdf)) {
      w = (have_f ? f : disney::eval(g.material, g.n, g.wo, l)) * (cos_l / pdf) * norm;
      if (!all_finite(w)) w = glm::vec3(0.0f);
      Ray shadow;
      shadow.origin = origin;
      shadow.direction = l;
      if (bvh.occluded(shadow)) w *= float(opt.ambient);  // blocked by the object itself
      if (full) full[k] = w;
      if (cv && all_finite(w)) w -= cv->c * ((1.0f + cv->kappa * disney::schlick_weight(cos_l)) * cos_l / pdf * norm);
    } else {
      l = g.n;
      if (units && !have_normal_unit) normal_unit = equirect::direction_to_unit(l.x, l.y, l.z), have_normal_unit = true;
      unit = normal_unit, have_unit = true;
      if (full) full[k] = glm::vec3(0.0f);
    }
    ls[k] = l;
    ws[k] = w;
    if (units) units[k] = have_unit ? unit : equirect::direction_to_unit(l.x, l.y, l.z);
  };
  if (inference && opt.bilinear_env_sampling) {
    bilinear_light_rays(sampling, env_map, g, point, rotations, aa, finish);
    return;
  }
  for (int k = 0; k < N; ++k) {
    glm::vec3 l, f(0.0f);
    float pdf;
    equirect::UV unit{0.5, 0.5};
    bool have_f = false, have_unit = false;
    const bool split = opt.importance_sampling && n_brdf > 0;
    const float u1 = split ? 0.0f : uniform01f(light_seed, g.stream, 2 * k);
    const float u2 = split ? 0.0f : uniform01f(light_seed, g.stream, 2 * k + 1);
    if (!opt.importance_sampling) {  // training: cosine-weighted hemisphere
      l = frame.to_world(cosine_hemisphere(u1, u2));
      pdf = cosine_hemisphere_pdf(glm::dot(l, g.n));
    } else if (n_brdf == 0) {  // a single sample: one-sample MIS (balance heuristic)
      if (uniform01f(choice_seed, g.stream, k) < 0.5f)
        l = disney::sample(g.material, g.n, g.wo, u1, u2, uniform01f(choice_seed, g.stream, k + N)).wi;
      else
        l = env_sample(env_map, opt, u1, u2);
      pdf = 0.5f * disney::pdf(g.material, g.n, g.wo, l) + 0.5f * env_pdf(env_map, opt, l);
    } else {  // inference with the texel sky sampler: the MIS of bilinear_light_rays(), per ray
      const SplitSample sp = split_sample(rotations, k, N, n_brdf, int(g.stream % uint64_t(aa)), aa);
      disney::Sample b;
      if (sp.technique == 0) {
        b = disney::sample(point, sp.u.x, sp.u.y, uniform01f(choice_seed, g.stream, k + N));
        l = b.wi;
      } else {
        l = env_map.sample(sp.u.x, sp.u.y).direction;
        b = disney::evaluate(point, l);
      }
      if (glm::dot(l, l) > 0.0f) {
        unit = equirect::direction_to_unit(l.x, l.y, l.z);  // l is unit (both techniques)
        have_unit = true;
      }
      const float pe = have_unit ? env_map.pdf(l) : 0.0f;
      pdf = c_brdf * b.pdf + c_env * pe;
      f = b.f;
      have_f = true;
    }
    finish(k, l, f, have_f, pdf, unit, have_unit);
  }
}

// Per pixel (in sample order), the offsets of its light rays.
void pixel_offsets(const std::vector<GSample>& gs, int N, Foreground& fg) {
  fg.offsets.assign(1, 0);
  for (size_t i = 0; i < gs.size(); ++i) {
    if (i == 0 || gs[i].pixel != gs[i - 1].pixel) {
      if (i > 0) fg.offsets.push_back(int64_t(i) * N);
      fg.pixels.push_back(gs[i].pixel);
    }
  }
  if (!gs.empty()) fg.offsets.push_back(int64_t(gs.size()) * N);
}

}  // namespace

// Pass 2: N light directions per G-buffer sample, written to fixed slots [i·N, (i+1)·N).
void trace_foreground(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map,
                      const std::vector<GSample>& gs, Foreground& fg, QueryRays& rays, bool control_variate) {
  const int N = fg.light_samples;
  const LightSampling sampling(opt, N);
  fg.weights.assign(gs.size() * size_t(N) * 3, 0.0f);
  parallel_for(int64_t(gs.size()), 16, [&](int64_t b, int64_t e) {
    std::vector<glm::vec3> ls(static_cast<size_t>(N)), ws(static_cast<size_t>(N));
    for (int64_t i = b; i < e; ++i) {
      const GSample& g = gs[size_t(i)];
      const disney::DiffuseControl cv =
          control_variate ? disney::diffuse_control(g.material, glm::dot(g.n, g.wo)) : disney::DiffuseControl{};
      light_rays(opt, sampling, bvh, env_map, g, control_variate ? &cv : nullptr, ls.data(), ws.data(), nullptr);
      const glm::vec3 origin = light_origin(g);
      for (int k = 0; k < N; ++k) {
        const int64_t slot = i * N + k;
        rays.set(slot, origin, ls[size_t(k)]);
        for (int c = 0; c < 3; ++c) fg.weights[size_t(3 * slot + c)] = ws[size_t(k)][c];
      }
    }
  });
  pixel_offsets(gs, N, fg);
}

std::vector<int> adaptive_extra_samples(const std::vector<double>& spread, const std::vector<int>& visible, int N,
                                        double budget, int cap) {
  const size_t P = spread.size();
  std::vector<int> extra(P, 0);
  double max_s = 0;
  for (size_t p = 0; p < P; ++p) max_s = std::max(max_s, std::isfinite(spread[p]) ? spread[p] : 0.0);
  if (!(budget > 0) || cap <= 0 || !(max_s > 0)) return extra;
  auto m_of = [&](double t, size_t p) {
    const double s = std::isfinite(spread[p]) ? spread[p] : 0.0;
    return std::clamp(t * s - N, 0.0, double(cap));
  };
  auto cost = [&](double t) {
    double c = 0;
    for (size_t p = 0; p < P; ++p) c += visible[p] * m_of(t, p);
    return c;
  };
  // The cost is non-decreasing in t; at hi every pixel with a spread is at its cap.
  double min_s = max_s;
  for (size_t p = 0; p < P; ++p)
    if (std::isfinite(spread[p]) && spread[p] > 0) min_s = std::min(min_s, spread[p]);
  double lo = 0, hi = (N + cap) / min_s;
  if (cost(hi) <= budget) {
    lo = hi;
  } else {
    for (int it = 0; it < 40; ++it) {  // 2^-40 of the bracket: far below the rounding to even
      const double mid = 0.5 * (lo + hi);
      (cost(mid) <= budget ? lo : hi) = mid;
    }
  }
  for (size_t p = 0; p < P; ++p) extra[p] = 2 * int(std::lround(0.5 * m_of(lo, p)));
  return extra;
}

void shade_foreground(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map,
                      const std::vector<GSample>& gs, const RadianceCache& cache, bool control_variate, Foreground& fg,
                      std::vector<float>& colour, const RayMarcher* exact) {
  const int N = fg.light_samples;
  pixel_offsets(gs, N, fg);
  const size_t P = fg.pixels.size();
  const bool adaptive = opt.adaptive_light_samples > 0 && N > 0;
  const bool denoise = opt.denoise_radius > 0 && control_variate;
  // Per sample: the Monte Carlo residual Σ w·L (pass 1), the control variate's c·E/aa, and
  // Σ (w·L)² per channel (for the pixels' spreads).
  std::vector<glm::vec3> residual(gs.size()), control(gs.size(), glm::vec3(0.0f)), squares;
  if (adaptive || denoise) squares.assign(gs.size(), glm::vec3(0.0f));
  // One sample's light rays under `sampling`: Σ w·L, and Σ (w·L)² into *sq when given.
  // `at` = cache.corners() of the sample's light origin.
  // With `full` (the weights without the control variate's term), also the sample's exact
  // correction into *correct (render/object_insertion.h, "Exact corrections").
  const int M = exact ? std::min({opt.cache_exact_light_rays, N, kMaxCorrections}) : 0;
  static thread_local std::vector<glm::vec3> lc;  // a sample's cached radiance per ray (corrections)
  static thread_local std::vector<float> score;
  // The corrections' rays of a run of samples, marched together (RayMarcher's batch, the same
  // bits) and then summed per sample in pick order, as if each had been marched when picked.
  struct PendingCorrection {
    glm::vec3* target;  // the sample's correction
    float weight;       // the pick's 1/(M·p)
    glm::vec3 w, cached;
  };
  static thread_local std::vector<PendingCorrection> pending;
  static thread_local std::vector<float> pending_origins, pending_dirs;
  static thread_local std::vector<RayMarcher::Result> pending_radiance;
  auto flush_corrections = [&] {
    const int64_t n = int64_t(pending.size());
    pending_radiance.resize(size_t(n));
    if (n > 0) (*exact)(n, pending_origins.data(), pending_dirs.data(), pending_radiance.data());
    for (int64_t a = 0; a < n;) {
      glm::vec3 c(0.0f);
      int64_t b = a;
      for (; b < n && pending[size_t(b)].target == pending[size_t(a)].target; ++b) {
        const PendingCorrection& p = pending[size_t(b)];
        c += p.weight * p.w * (pending_radiance[size_t(b)].radiance - p.cached);
      }
      *pending[size_t(a)].target = all_finite(c) ? c : glm::vec3(0.0f);
      a = b;
    }
    pending.clear();
    pending_origins.clear();
    pending_dirs.clear();
  };
  const uint64_t exact_seed = hash_counter(sample_seed(opt, kTagLight), kTagExact);
  std::atomic<int64_t> exact_rays{0};
  auto trace = [&](const LightSampling& sampling, const GSample& g, const disney::DiffuseControl* cv,
                   const RadianceCache::Corners& at, std::vector<glm::vec3>& ls, std::vector<glm::vec3>& ws,
                   std::vector<equirect::UV>& units, glm::vec3* sq, std::vector<glm::vec3>* full = nullptr,
                   glm::vec3* correct = nullptr) {
    const int n = sampling.N;
    if (int(ls.size()) < n) {
      ls.resize(size_t(n));
      ws.resize(size_t(n));
      units.resize(size_t(n));
    }
    if (full && int(full->size()) < n) full->resize(size_t(n));
    light_rays(opt, sampling, bvh, env_map, g, cv, ls.data(), ws.data(), units.data(), full ? full->data() : nullptr);
    glm::vec3 acc(0.0f), acc2(0.0f);
    const bool correcting = full && correct && M > 0;
    if (correcting && int(lc.size()) < n) lc.resize(size_t(n)), score.resize(size_t(n));
    for (int k = 0; k < n; ++k) {
      if (correcting) lc[size_t(k)] = glm::vec3(0.0f), score[size_t(k)] = 0.0f;
      if (ws[size_t(k)] != glm::vec3(0.0f) || (correcting && (*full)[size_t(k)] != glm::vec3(0.0f))) {
        const glm::vec3 L = cache.radiance_unit(at, units[size_t(k)]);
        const glm::vec3 t = ws[size_t(k)] * L;
        acc += t;
        acc2 += t * t;
        if (correcting) {
          lc[size_t(k)] = L;
          const glm::vec3 f = (*full)[size_t(k)] * L;
          score[size_t(k)] = std::abs(f.x) + std::abs(f.y) + std::abs(f.z);
        }
      }
    }
    if (correcting) {
      // M of the n rays, drawn in proportion to their cached contribution (render/exact_correction.h).
      CorrectionPick picks[kMaxCorrections];
      const int m = pick_corrections(score.data(), n, M, uniform01f(exact_seed, g.stream, 0), picks);
      int marched = 0;
      for (int j = 0; j < m; ++j) {
        const int k = picks[j].index;
        const glm::vec3 w = (*full)[size_t(k)];
        if (w == glm::vec3(0.0f)) continue;
        const glm::vec3 l = ls[size_t(k)];
        pending.push_back({correct, picks[j].weight, w, lc[size_t(k)]});
        pending_origins.insert(pending_origins.end(), {at.origin.x, at.origin.y, at.origin.z});
        pending_dirs.insert(pending_dirs.end(), {l.x, l.y, l.z});
        ++marched;
      }
      exact_rays.fetch_add(marched, std::memory_order_relaxed);
      *correct = glm::vec3(0.0f);  // until flush_corrections() sums its picks
    }
    if (sq) *sq = acc2;
    return acc;
  };
  const LightSampling first(opt, N);
  std::vector<glm::vec3> correction(M > 0 ? gs.size() : 0, glm::vec3(0.0f));
  // Dynamic: a sample's cost depends on where it sees the sun and the object, so the two halves
  // of a static split differ; on KITTI 000008 one thread slept 40 ms at this loop's end (perf).
  parallel_for_dynamic(int64_t(gs.size()), 128, [&](int64_t b, int64_t e) {
    std::vector<glm::vec3> ls, ws, full;
    std::vector<equirect::UV> units;
    for (int64_t i = b; i < e; ++i) {
      const GSample& g = gs[size_t(i)];
      const disney::DiffuseControl cv =
          control_variate ? disney::diffuse_control(g.material, glm::dot(g.n, g.wo)) : disney::DiffuseControl{};
      const glm::vec3 origin = light_origin(g);
      const RadianceCache::Corners at = cache.corners(&origin[0]);
      residual[size_t(i)] = trace(first, g, control_variate ? &cv : nullptr, at, ls, ws, units,
                                  squares.empty() ? nullptr : &squares[size_t(i)], M > 0 ? &full : nullptr,
                                  M > 0 ? &correction[size_t(i)] : nullptr);
      if (control_variate) {
        const RadianceCache::Irradiance e = cache.irradiance(at, g.n);
        control[size_t(i)] = cv.c * (e.cosine + cv.kappa * e.grazing) / float(opt.aa_samples);
      }
      if (pending.size() >= 64) flush_corrections();
    }
    flush_corrections();
  });
  auto samples_of = [&](size_t p) { return std::pair<int64_t, int64_t>{fg.offsets[p] / N, fg.offsets[p + 1] / N}; };
  const PixelWindow window(fg.pixels, fg.width);
  // Per pixel: the first pass's residual, and the variance of one light sample's term (summed
  // over channels).
  std::vector<glm::vec3> first_sum(P, glm::vec3(0.0f));
  std::vector<double> sample_var(P, 0.0);
  parallel_for(int64_t(P), 1024, [&](int64_t b, int64_t e) {
    for (size_t p = size_t(b); p < size_t(e); ++p) {
      const auto [i0, i1] = samples_of(p);
      glm::dvec3 s1(0.0), s2(0.0);
      for (int64_t i = i0; i < i1; ++i) {
        s1 += glm::dvec3(residual[size_t(i)]);
        if (!squares.empty()) s2 += glm::dvec3(squares[size_t(i)]);
      }
      first_sum[p] = glm::vec3(s1);
      const double count = double(i1 - i0) * N;
      const glm::dvec3 mean = s1 / count, var = glm::max(s2 / count - mean * mean, glm::dvec3(0.0));
      sample_var[p] = var.x + var.y + var.z;
    }
  });
  // Adaptive: the extra samples per pixel, and the second pass over the pixels that got some.
  std::vector<int> extra(P, 0);
  std::vector<glm::vec3> second;
  if (adaptive) {
    // A pixel's spread is the mean of its object neighbours' (3×3, itself left out): its extra
    // samples then do not depend on its own first pass, so the blend stays unbiased.
    std::vector<double> spread(P, 0.0);
    std::vector<int> visible(P, 0);
    parallel_for(int64_t(P), 1024, [&](int64_t b, int64_t e) {
      for (size_t p = size_t(b); p < size_t(e); ++p) {
        visible[p] = int(samples_of(p).second - samples_of(p).first);
        double sum = 0;
        int n = 0;
        window.for_neighbours(p, 1, [&](size_t q) {
          if (q == p) return;
          sum += std::sqrt(sample_var[q]);
          ++n;
        });
        spread[p] = n > 0 ? sum / n : 0.0;
      }
    });
    extra = adaptive_extra_samples(spread, visible, N, opt.adaptive_light_samples * double(gs.size()),
                                   opt.adaptive_max_factor * N);
    std::vector<int64_t> todo;  // samples of pixels with extra > 0
    for (size_t p = 0; p < P; ++p) {
      if (extra[p] == 0) continue;
      for (int64_t i = samples_of(p).first; i < samples_of(p).second; ++i) todo.push_back(i);
      fg.extra_light_rays += int64_t(extra[p]) * (samples_of(p).second - samples_of(p).first);
    }
    std::vector<int> extra_of(gs.size(), 0);
    for (size_t p = 0; p < P; ++p)
      for (int64_t i = samples_of(p).first; i < samples_of(p).second; ++i) extra_of[size_t(i)] = extra[p];
    second.assign(gs.size(), glm::vec3(0.0f));
    parallel_for_dynamic(int64_t(todo.size()), 4, [&](int64_t b, int64_t e) {
      std::vector<glm::vec3> ls, ws;
      std::vector<equirect::UV> units;
      for (int64_t t = b; t < e; ++t) {
        const size_t i = size_t(todo[size_t(t)]);
        const GSample& g = gs[i];
        const LightSampling more(opt, extra_of[i], kTagAdaptive);
        const disney::DiffuseControl cv =
            control_variate ? disney::diffuse_control(g.material, glm::dot(g.n, g.wo)) : disney::DiffuseControl{};
        const glm::vec3 origin = light_origin(g);
        second[i] = trace(more, g, control_variate ? &cv : nullptr, cache.corners(&origin[0]), ls, ws, units, nullptr);
      }
    });
  }
  // Per pixel: the residual (both passes blended by their counts) and the control's integral.
  std::vector<DenoisePixel> px(P);
  std::vector<glm::vec3> fixes(correction.empty() ? 0 : P, glm::vec3(0.0f));
  parallel_for(int64_t(P), 1024, [&](int64_t b, int64_t e) {
    for (size_t p = size_t(b); p < size_t(e); ++p) {
      const auto [i0, i1] = samples_of(p);
      glm::vec3 r2(0.0f), c(0.0f), n(0.0f), x(0.0f), fix(0.0f);
      for (int64_t i = i0; i < i1; ++i) {
        c += control[size_t(i)];
        if (!correction.empty()) fix += correction[size_t(i)];
        n += gs[size_t(i)].n;
        x += gs[size_t(i)].x / float(i1 - i0);
        if (!second.empty()) r2 += second[size_t(i)];
      }
      const int m = extra[p];
      DenoisePixel& d = px[p];
      d.residual = m > 0 ? (float(N) * first_sum[p] + float(m) * r2) / float(N + m) : first_sum[p];
      // The exact correction estimates E[L_exact − L_cached] for both passes' rays alike.
      if (!correction.empty()) fixes[p] = fix;
      d.control = c;
      d.normal = safe_normalize(n);
      d.position = x;
      d.depth = fg.depth[size_t(fg.pixels[p])];
      // The variance of the residual's channel sum: (samples in the first pass) × (one term's),
      // scaled by the blend's weight N/(N + m) of that pass (the second's terms are alike).
      d.variance = float(sample_var[p] * double(i1 - i0) * N * double(N) / double(N + m));
    }
  });
  fg.exact_correction_rays = exact_rays.load();
  const std::vector<glm::vec3> r = denoise ? denoise_residual(px, window, opt) : std::vector<glm::vec3>{};
  // The correction's noise is the cache's per-ray error, its mean the probes' bias, which changes
  // over a probe cell (many pixels): it gets its own, wider filter, guided by normals and depth.
  std::vector<glm::vec3> fixed;
  if (!fixes.empty()) {
    std::vector<DenoisePixel> fx = px;
    for (size_t p = 0; p < P; ++p) fx[p].residual = fixes[p];
    InsertionOptions fopt = opt;
    fopt.denoise_radius = opt.cache_exact_filter_radius;
    fopt.denoise_variance_sigma = 0;
    fixed = denoise_residual(fx, window, fopt);
  }
  colour.assign(size_t(3 * P), 0.0f);
  for (size_t p = 0; p < P; ++p) {
    const glm::vec3 acc = px[p].control + (denoise ? r[p] : px[p].residual) + (fixed.empty() ? glm::vec3(0.0f) : fixed[p]);
    // A control-variate estimate can dip below 0 where the object blocks much of its own light
    // (3 of 1.4M values on KITTI 000008, the lowest −0.011); radiance cannot.
    for (int ch = 0; ch < 3; ++ch) colour[3 * p + size_t(ch)] = std::max(0.0f, acc[ch]);
  }
}

}  // namespace sl::render::insertion
