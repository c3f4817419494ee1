// insert_objects(): Sec 3.3 — foreground (Eq. 2), ratio shadows (Eq. 3-4), compositing.
// Geometry, materials and sampling are constants; the lighting (env, vsg) is on the tape. All
// light and shadow rays go through ONE radiance query; two segment reductions and a few
// gather/scatter ops assemble the image.
#include "render/object_insertion.h"

#include <algorithm>
#include <cmath>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "render/disney_brdf.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/insertion_ops.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl {
namespace {

constexpr uint64_t kTagAa = 0xA11A5EEDull, kTagLight = 0x11647ull, kTagShadow = 0x5AD0Eull, kTagChoice = 0xC401CEull;

constexpr uint64_t kTagRotation = 0x2071A7Eull;

bool valid_depth(double d) { return std::isfinite(d) && d > 0.0; }

// The seed of one family of light/shadow samples; lighting_seed = 0 leaves the seeds of
// earlier versions unchanged (the trainer's bits do not move).
uint64_t sample_seed(const InsertionOptions& opt, uint64_t tag) {
  const uint64_t base = hash_counter(opt.seed, tag);
  return opt.lighting_seed == 0 ? base : hash_counter(base, opt.lighting_seed);
}

float radical_inverse2(uint32_t i) {
  i = (i << 16) | (i >> 16);
  i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
  i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
  i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
  i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
  return float(i) * 0x1.0p-32f;
}

float wrap01(float x) {
  x -= std::floor(x);
  return x < 1.0f ? x : 0.0f;
}

// Point j of an m-point Hammersley set, shifted by (r1, r2) modulo 1 (Cranley-Patterson):
// stratified in both coordinates, and unbiased because the shift is uniform.
glm::vec2 rotated_hammersley(int j, int m, float r1, float r2) {
  return {wrap01((float(j) + 0.5f) / float(m) + r1), wrap01(radical_inverse2(uint32_t(j)) + r2)};
}

// Inference: sample k of n goes to technique 0 (k < n0) or 1, and is point j of its technique's
// stratified set; the rotation is per stream and technique.
struct SplitSample {
  int technique;
  glm::vec2 u;
};
SplitSample split_sample(uint64_t rot_seed, uint64_t stream, int k, int n, int n0) {
  const int technique = k < n0 ? 0 : 1, j = technique == 0 ? k : k - n0, m = technique == 0 ? n0 : n - n0;
  const float r1 = uniform01f(rot_seed, stream, 2 * technique), r2 = uniform01f(rot_seed, stream, 2 * technique + 1);
  return {technique, rotated_hammersley(j, m, r1, r2)};
}

float ray_epsilon(const glm::vec3& p) { return 1e-3f + 1e-4f * glm::length(p); }

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

// Rays leaving the object or the ground, in a fixed layout (slot i is written by one thread).
struct QueryRays {
  std::vector<float> origin, dir;  // 3 per ray
  void resize(int64_t n) {
    origin.assign(size_t(3 * n), 0.0f);
    dir.assign(size_t(3 * n), 0.0f);
  }
  void set(int64_t i, const glm::vec3& o, const glm::vec3& d) {
    for (int c = 0; c < 3; ++c) {
      origin[size_t(3 * i + c)] = o[c];
      dir[size_t(3 * i + c)] = d[c];
    }
  }
  int64_t size() const { return int64_t(origin.size() / 3); }
};

// Pixel rectangle [x0, x1) × [y0, y1) that the object's box covers (the whole image when a
// corner is behind the camera, or when pruning is off).
struct Rect {
  int x0, y0, x1, y1;
  int64_t area() const { return int64_t(std::max(0, x1 - x0)) * std::max(0, y1 - y0); }
};

Rect screen_bounds(const Bounds3& b, const Camera& cam, bool prune) {
  const int W = cam.intrinsics().width, H = cam.intrinsics().height;
  if (!prune) return {0, 0, W, H};
  double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? b.hi.x : b.lo.x, (c & 2) ? b.hi.y : b.lo.y, (c & 4) ? b.hi.z : b.lo.z);
    const Projection pr = cam.project(p);
    if (!pr.in_front) return {0, 0, W, H};
    u0 = std::min(u0, pr.pixel.x);
    u1 = std::max(u1, pr.pixel.x);
    v0 = std::min(v0, pr.pixel.y);
    v1 = std::max(v1, pr.pixel.y);
  }
  return {std::clamp(int(std::floor(u0)), 0, W), std::clamp(int(std::floor(v0)), 0, H),
          std::clamp(int(std::ceil(u1)) + 1, 0, W), std::clamp(int(std::ceil(v1)) + 1, 0, H)};
}

bool ray_hits_box(const glm::vec3& o, const glm::vec3& d, const Bounds3& b) {
  float t0 = 0.0f, t1 = 1e30f;
  for (int a = 0; a < 3; ++a) {
    const float inv = 1.0f / d[a];
    float ta = (b.lo[a] - o[a]) * inv, tb = (b.hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, std::isnan(ta) ? t0 : ta);
    t1 = std::min(t1, std::isnan(tb) ? t1 : tb);
  }
  return t0 <= t1;
}

struct Foreground {
  std::vector<int64_t> pixels;   // image pixels with at least one visible sample
  std::vector<int64_t> offsets;  // per pixel, into the light rays
  std::vector<float> weights;    // 3 per light ray: f·cos/pdf / (N·aa), × I_a when self-occluded
  std::vector<float> coverage, depth;  // per image pixel
  std::vector<float> silhouette;       // per image pixel: coverage before the photo's occlusion
  int light_samples = 0;         // N actually used
};

// A visible primary sample: the G-buffer entry of Eq. 2.
struct GSample {
  int64_t pixel;
  uint64_t stream;  // counter-RNG stream of its light samples
  glm::vec3 x, n, wo;
  disney::Params material;
};

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
  const uint64_t aa_seed = hash_counter(opt.seed, kTagAa);
  std::vector<std::vector<GSample>> rows(size_t(std::max(0, r.y1 - r.y0)));
  parallel_for(int64_t(rows.size()), 1, [&](int64_t b, int64_t e) {
    for (int64_t ri = b; ri < e; ++ri) {
      const int row = r.y0 + int(ri);
      for (int col = r.x0; col < r.x1; ++col) {
        const int64_t pix = int64_t(row) * W + col;
        int visible = 0, hits = 0;
        double zsum = 0;
        for (int s = 0; s < opt.aa_samples; ++s) {
          const double u = col + uniform01(aa_seed, uint64_t(pix), 2 * s), v = row + uniform01(aa_seed, uint64_t(pix), 2 * s + 1);
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
  std::vector<GSample> all;
  for (auto& row : rows) all.insert(all.end(), row.begin(), row.end());
  stats.foreground_samples = int64_t(all.size());
  return all;
}

// Pass 2: N light directions per G-buffer sample, written to fixed slots [i·N, (i+1)·N).
void trace_foreground(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map,
                      const std::vector<GSample>& gs, Foreground& fg, QueryRays& rays) {
  const int N = fg.light_samples;
  const uint64_t light_seed = sample_seed(opt, kTagLight), choice_seed = sample_seed(opt, kTagChoice);
  const uint64_t rot_seed = sample_seed(opt, kTagRotation);
  const int n_brdf = N / 2;  // inference: BRDF samples first, then environment samples
  const float c_brdf = float(n_brdf) / float(N), c_env = 1.0f - c_brdf;
  fg.weights.assign(gs.size() * size_t(N) * 3, 0.0f);
  const float norm = 1.0f / float(N * opt.aa_samples);
  parallel_for(int64_t(gs.size()), 16, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const GSample& g = gs[size_t(i)];
      const Frame frame(g.n);
      const glm::vec3 origin = g.x + ray_epsilon(g.x) * g.n;
      for (int k = 0; k < N; ++k) {
        glm::vec3 l;
        float pdf;
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
            l = env_map.sample(u1, u2).direction;
          pdf = 0.5f * disney::pdf(g.material, g.n, g.wo, l) + 0.5f * env_map.pdf(l);
        } else {  // inference: stratified multi-sample MIS of BRDF and environment sampling
          const SplitSample sp = split_sample(rot_seed, g.stream, k, N, n_brdf);
          if (sp.technique == 0)
            l = disney::sample(g.material, g.n, g.wo, sp.u.x, sp.u.y, uniform01f(choice_seed, g.stream, k + N)).wi;
          else
            l = env_map.sample(sp.u.x, sp.u.y).direction;
          pdf = c_brdf * disney::pdf(g.material, g.n, g.wo, l) + c_env * env_map.pdf(l);
        }
        const float cos_l = glm::dot(l, g.n);
        glm::vec3 w(0.0f);
        if (cos_l > 0 && pdf > 0 && std::isfinite(pdf)) {
          w = disney::eval(g.material, g.n, g.wo, l) * (cos_l / pdf) * norm;
          if (!all_finite(w)) w = glm::vec3(0.0f);
          Ray shadow;
          shadow.origin = origin;
          shadow.direction = l;
          if (bvh.occluded(shadow)) w *= float(opt.ambient);  // blocked by the object itself
        } else {
          l = g.n;  // a harmless ray with zero weight keeps the layout regular
        }
        const int64_t slot = i * N + k;
        rays.set(slot, origin, l);
        for (int c = 0; c < 3; ++c) fg.weights[size_t(3 * slot + c)] = w[c];
      }
    }
  });
  fg.offsets.assign(1, 0);
  for (size_t i = 0; i < gs.size(); ++i) {
    if (i == 0 || gs[i].pixel != gs[i - 1].pixel) {
      if (i > 0) fg.offsets.push_back(int64_t(i) * N);
      fg.pixels.push_back(gs[i].pixel);
    }
  }
  if (!gs.empty()) fg.offsets.push_back(int64_t(gs.size()) * N);
}

struct Shadows {
  std::vector<int64_t> texels;   // shadow-map texels computed
  std::vector<int64_t> offsets;  // per texel, into the shadow rays (relative to their start)
  std::vector<double> visibility;
  std::vector<double> weights;       // cos/pdf per shadow ray
  std::vector<float> texel_depth;  // per texel of the whole map (0 = hole)
};

// The k-th shadow direction of texel t and its weight cos/pdf (0 marks an unusable sample).
struct ShadowSampler {
  const InsertionOptions& opt;
  const EnvironmentMap& env_map;
  uint64_t seed, choice_seed, rot_seed;
  Frame frame{glm::vec3(0, 1, 0)};
  std::pair<glm::vec3, double> operator()(int64_t t, int k) const {
    if (!opt.importance_sampling) {
      const float u1 = uniform01f(seed, uint64_t(t), 2 * k), u2 = uniform01f(seed, uint64_t(t), 2 * k + 1);
      return {frame.to_world(cosine_hemisphere(u1, u2)), 1.0};  // w = π cancels
    }
    // Inference: cosine + environment samples, so a hard sun is found; split and stratified
    // (a single ray: one-sample mixture).
    const int N = opt.shadow_rays, n_cos = N / 2;
    glm::vec3 d;
    double c_cos = 0.5;
    if (n_cos == 0) {
      const float u1 = uniform01f(seed, uint64_t(t), 2 * k), u2 = uniform01f(seed, uint64_t(t), 2 * k + 1);
      d = uniform01f(choice_seed, uint64_t(t), k) < 0.5f ? frame.to_world(cosine_hemisphere(u1, u2))
                                                         : env_map.sample(u1, u2).direction;
    } else {
      const SplitSample sp = split_sample(rot_seed, uint64_t(t), k, N, n_cos);
      d = sp.technique == 0 ? frame.to_world(cosine_hemisphere(sp.u.x, sp.u.y)) : env_map.sample(sp.u.x, sp.u.y).direction;
      c_cos = double(n_cos) / N;
    }
    const double cos_t = d.y, pdf = c_cos * std::max(0.0, cos_t) / kPi + (1.0 - c_cos) * env_map.pdf(d);
    return {d, (cos_t > 0 && pdf > 0) ? cos_t / pdf : 0.0};
  }
};

// Pass 1 decides which texels need rays (those with depth whose rays can meet the object's box);
// pass 2 writes their rays into fixed slots (the caller appends them after the light rays).
void trace_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box, const Bvh& bvh,
                   const EnvironmentMap& env_map, const double* depth, Shadows& sh, QueryRays& rays,
                   InsertionStats& stats) {
  const Camera& cam = in.camera;
  const int W = cam.intrinsics().width, H = cam.intrinsics().height;
  const int sw = opt.shadow_width, shh = opt.shadow_height, N = opt.shadow_rays;
  const int64_t n_texels = int64_t(sw) * shh;
  const ShadowSampler sampler{opt, env_map, sample_seed(opt, kTagShadow), sample_seed(opt, kTagChoice + 1),
                              sample_seed(opt, kTagRotation + 1)};
  const glm::vec3 up(0, 1, 0);
  sh.texel_depth.assign(size_t(n_texels), 0.0f);
  std::vector<glm::vec3> origin(static_cast<size_t>(n_texels));
  std::vector<uint8_t> needed(size_t(n_texels), 0);
  parallel_for(n_texels, 16, [&](int64_t b, int64_t e) {
    for (int64_t t = b; t < e; ++t) {
      const double u = (t % sw + 0.5) * W / sw, v = (t / sw + 0.5) * H / shh;
      const double d = depth[std::min<int64_t>(H - 1, int64_t(v)) * W + std::min<int64_t>(W - 1, int64_t(u))];
      if (!valid_depth(d)) continue;  // a hole (sky, missing depth): S = 1
      sh.texel_depth[size_t(t)] = float(d);
      const glm::vec3 x(cam.unproject(u, v, d));
      origin[size_t(t)] = x + ray_epsilon(x) * up;
      // Only rays with d.y > 0 carry weight; a box wholly below the origin meets none of them.
      if (opt.prune && box.hi.y <= origin[size_t(t)].y) continue;
      bool any = !opt.prune;
      for (int k = 0; k < N && !any; ++k) any = ray_hits_box(origin[size_t(t)], sampler(t, k).first, box);
      needed[size_t(t)] = any ? 1 : 0;  // none can meet the object: S = 1 exactly
    }
  });
  for (int64_t t = 0; t < n_texels; ++t)
    if (needed[size_t(t)]) sh.texels.push_back(t);
  const int64_t count = int64_t(sh.texels.size());
  stats.shadow_pixels_total = n_texels;
  stats.shadow_pixels_computed = count;
  sh.offsets.resize(size_t(count) + 1);
  for (int64_t i = 0; i <= count; ++i) sh.offsets[size_t(i)] = i * N;
  rays.resize(count * N);
  sh.visibility.assign(size_t(count * N), 1.0);
  sh.weights.assign(size_t(count * N), 0.0);
  parallel_for(count, 4, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const int64_t t = sh.texels[size_t(i)];
      const glm::vec3 o = origin[size_t(t)];
      for (int k = 0; k < N; ++k) {
        const auto [dir, w] = sampler(t, k);
        const size_t slot = size_t(i * N + k);
        Ray r;
        r.origin = o;
        r.direction = dir;
        sh.visibility[slot] = w > 0 && bvh.occluded(r) ? opt.ambient : 1.0;
        sh.weights[slot] = w;
        rays.set(int64_t(slot), o, w > 0 ? dir : up);
      }
    }
  });
}

// Edge-aware upsampling taps: 4 bilinear texels per image pixel, weighted by depth similarity
// (σ = 5% of the pixel's depth), renormalised. Index `n_texels` is a constant-1 row for pixels
// with no depth.
void upsample_taps(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                   std::vector<int64_t>& idx, std::vector<double>& w) {
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  const int sw = opt.shadow_width, shh = opt.shadow_height;
  const int64_t one_row = int64_t(sw) * shh;
  idx.assign(size_t(W) * H * 4, one_row);
  w.assign(size_t(W) * H * 4, 0.0);
  parallel_for(H, 4, [&](int64_t r0, int64_t r1) {
    for (int row = int(r0); row < int(r1); ++row)
      for (int col = 0; col < W; ++col) {
        const int64_t p = int64_t(row) * W + col;
        const double dp = depth[p];
        if (!valid_depth(dp)) {
          w[4 * p] = 1.0;
          continue;
        }
        const double fx = (col + 0.5) * sw / W - 0.5, fy = (row + 0.5) * shh / H - 0.5;
        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
        const double ax = fx - x0, ay = fy - y0;
        double total = 0;
        for (int c = 0; c < 4; ++c) {
          const int x = std::clamp(x0 + (c & 1), 0, sw - 1), y = std::clamp(y0 + (c >> 1), 0, shh - 1);
          const int64_t t = int64_t(y) * sw + x;
          const double bil = ((c & 1) ? ax : 1 - ax) * ((c >> 1) ? ay : 1 - ay);
          const double dt = sh.texel_depth[t];
          const double sim = dt > 0 ? std::exp(-0.5 * std::pow((dp - dt) / (0.05 * dp), 2)) : 0.0;
          idx[4 * p + c] = dt > 0 ? t : one_row;
          w[4 * p + c] = bil * std::max(sim, 1e-12);
          total += w[4 * p + c];
        }
        for (int c = 0; c < 4; ++c) w[4 * p + c] = total > 0 ? w[4 * p + c] / total : (c == 0 ? 1.0 : 0.0);
      }
  });
}

// The radiance cache of the header: V = Σ τ α G and τ_K per probe and direction, read
// trilinearly × bilinearly; L_env is looked up exactly per ray.
class RadianceCache {
 public:
  RadianceCache(const InsertionInputs& in, const InsertionOptions& opt, const EnvironmentMap& env_map,
                const QueryRays& rays)
      : env_map_(env_map), H_(opt.cache_height), W_(opt.cache_width) {
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (int64_t r = 0; r < rays.size(); ++r) {
      const glm::vec3 o(rays.origin[size_t(3 * r)], rays.origin[size_t(3 * r + 1)], rays.origin[size_t(3 * r + 2)]);
      lo = glm::min(lo, o);
      hi = glm::max(hi, o);
    }
    lo_ = lo;
    for (int a = 0; a < 3; ++a) {
      const float ext = std::max(0.0f, hi[a] - lo[a]);
      n_[a] = std::clamp(int(std::ceil(ext / opt.cache_spacing_m)) + 1, 2, a == 1 ? 3 : 4);
      step_[a] = ext > 0 ? ext / float(n_[a] - 1) : 1.0f;
    }
    const int64_t D = int64_t(H_) * W_, P = int64_t(n_[0]) * n_[1] * n_[2];
    std::vector<float> o(size_t(3 * P * D)), d(size_t(3 * P * D));
    std::vector<glm::vec3> dirs(static_cast<size_t>(D));
    for (int64_t t = 0; t < D; ++t) {
      const equirect::Dir e = equirect::uv_to_direction(double(t % W_) + 0.5, double(t / W_) + 0.5, W_, H_);
      dirs[size_t(t)] = glm::vec3(float(e.x), float(e.y), float(e.z));
    }
    for (int64_t p = 0; p < P; ++p)
      for (int64_t t = 0; t < D; ++t)
        for (int c = 0; c < 3; ++c) {
          o[size_t(3 * (p * D + t) + c)] = probe(p)[c];
          d[size_t(3 * (p * D + t) + c)] = dirs[size_t(t)][c];
        }
    Tensor ot = Tensor::empty({P * D, 3}, DType::F32), dt = Tensor::empty({P * D, 3}, DType::F32);
    std::copy(o.begin(), o.end(), ot.data<float>());
    std::copy(d.begin(), d.end(), dt.data<float>());
    const RadianceQueryResult q = radiance_query(in.vsg.detach().to(DType::F32).contiguous(),
                                                 in.env.detach().to(DType::F32).contiguous(), ot, dt, in.grid, opt.query);
    const Tensor rad = q.radiance.contiguous(), tau = q.transmittance.contiguous();
    const float* rp = rad.data<float>();
    const float* tp = tau.data<float>();
    cache_.resize(size_t(4 * P * D));
    for (int64_t i = 0; i < P * D; ++i) {
      const glm::vec3 sky = env_map_.lookup(dirs[size_t(i % D)]);
      for (int c = 0; c < 3; ++c) cache_[size_t(4 * i + c)] = rp[3 * i + c] - tp[i] * sky[c];
      cache_[size_t(4 * i + 3)] = tp[i];
    }
  }

  glm::vec3 radiance(const float* origin, const float* dir) const {
    const glm::vec3 l(dir[0], dir[1], dir[2]);
    if (!(glm::dot(l, l) > 0.0f) || !all_finite(l)) return glm::vec3(0.0f);
    int i0[3];
    float f[3];
    for (int a = 0; a < 3; ++a) {
      const float x = std::clamp((origin[a] - lo_[a]) / step_[a], 0.0f, float(n_[a] - 1));
      i0[a] = std::min(int(x), n_[a] - 2);
      f[a] = x - float(i0[a]);
    }
    const EnvTaps taps = env_bilinear_taps(l.x, l.y, l.z, W_, H_);
    const int64_t D = int64_t(H_) * W_;
    glm::vec4 acc(0.0f);
    for (int c = 0; c < 8; ++c) {
      const int ix = i0[0] + (c & 1), iy = i0[1] + ((c >> 1) & 1), iz = i0[2] + (c >> 2);
      const float wc = ((c & 1) ? f[0] : 1 - f[0]) * (((c >> 1) & 1) ? f[1] : 1 - f[1]) * ((c >> 2) ? f[2] : 1 - f[2]);
      if (wc == 0.0f) continue;
      const float* base = &cache_[size_t(4 * ((int64_t(iz) * n_[1] + iy) * n_[0] + ix) * D)];
      for (int k = 0; k < 4; ++k) {
        const float w = wc * float(taps.weight[k]);
        const float* e = base + 4 * taps.index[k];
        acc += w * glm::vec4(e[0], e[1], e[2], e[3]);
      }
    }
    return glm::vec3(acc) + acc.w * env_map_.lookup(glm::normalize(l));
  }

 private:
  glm::vec3 probe(int64_t p) const {
    const int ix = int(p % n_[0]), iy = int(p / n_[0] % n_[1]), iz = int(p / (int64_t(n_[0]) * n_[1]));
    return lo_ + glm::vec3(float(ix) * step_[0], float(iy) * step_[1], float(iz) * step_[2]);
  }
  const EnvironmentMap& env_map_;
  int H_, W_;
  glm::vec3 lo_{0.0f};
  int n_[3] = {2, 2, 2};
  float step_[3] = {1, 1, 1};
  std::vector<float> cache_;  // [probe][direction][V rgb, τ]
};

void validate(const InsertionInputs& in, const InsertionOptions& opt) {
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  SL_CHECK(in.background.dim() == 3 && in.background.size(0) == 3 && in.background.size(1) == H &&
               in.background.size(2) == W,
           "insert_objects: background ", in.background.describe(), " does not match the camera's ", W, "x", H);
  SL_CHECK(in.depth.dim() == 2 && in.depth.size(0) == H && in.depth.size(1) == W, "insert_objects: depth ",
           in.depth.describe(), " does not match the camera's ", W, "x", H, " image");
  SL_CHECK(in.env.dim() == 3 && in.env.size(0) == 3, "insert_objects: env must be [3, H, W], got ", in.env.describe());
  SL_CHECK(!in.vsg.defined() || in.vsg.dtype() == in.env.dtype(), "insert_objects: vsg ", in.vsg.describe(),
           " and env ", in.env.describe(), " differ in dtype");
  SL_CHECK(opt.aa_samples >= 1 && opt.light_samples >= 1 && opt.shadow_rays >= 1, "insert_objects: sample counts (aa ",
           opt.aa_samples, ", light ", opt.light_samples, ", shadow ", opt.shadow_rays, ") must be >= 1");
  SL_CHECK(opt.shadow_width >= 1 && opt.shadow_height >= 1, "insert_objects: shadow map ", opt.shadow_width, "x",
           opt.shadow_height, " is empty");
  SL_CHECK(opt.ambient >= 0 && opt.ambient <= 1, "insert_objects: ambient I_a = ", opt.ambient, " must be in [0, 1]");
  SL_CHECK(!opt.radiance_cache || (opt.cache_height >= 2 && opt.cache_width >= 2 && opt.cache_spacing_m > 0),
           "insert_objects: radiance cache ", opt.cache_width, "x", opt.cache_height, " with spacing ",
           opt.cache_spacing_m, " m is invalid");
  SL_CHECK(!opt.radiance_cache || !grad_enabled() ||
               !(in.env.requires_grad() || (in.vsg.defined() && in.vsg.requires_grad())),
           "insert_objects: radiance_cache is for inference; gradients into env/vsg need exact queries");
}

Tensor as_tensor(const std::vector<float>& v, const Shape& shape, DType dt) {
  Tensor t = Tensor::empty(shape, DType::F32);
  std::copy(v.begin(), v.end(), t.data<float>());
  return t.to(dt);
}

}  // namespace

InsertionResult insert_objects(const InsertionInputs& in, const InsertionOptions& opt) {
  validate(in, opt);
  const DType dt = in.env.dtype();
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  const int64_t HW = int64_t(W) * H;
  InsertionResult out;

  // One object: its own BVH, built once by place_object() and reused across calls.
  Mesh merged;
  std::shared_ptr<const Bvh> own;
  if (in.objects.size() == 1 && in.objects[0].bvh) {
    own = in.objects[0].bvh;
  } else {
    for (const PlacedObject& o : in.objects) merged.append(o.mesh);
    own = std::make_shared<const Bvh>(merged);
  }
  const Mesh& mesh = in.objects.size() == 1 && in.objects[0].bvh ? in.objects[0].mesh : merged;
  const Bvh& bvh = *own;
  const Tensor depth_t = in.depth.detach().to(DType::F64).contiguous();
  const double* depth = depth_t.data<double>();
  const EnvironmentMap env_map(in.env.detach());

  Foreground fg;
  Shadows sh;
  QueryRays rays;
  std::vector<GSample> gs;
  if (!bvh.empty()) {
    gs = gbuffer(in, opt, mesh, bvh, depth, fg, out.stats);
    // Eq. 2's N: fixed per sample, or a total ray budget spread over the visible samples (the
    // paper samples 5000 foreground rays in training).
    fg.light_samples = opt.foreground_rays > 0
                           ? int(std::max<int64_t>(1, opt.foreground_rays / std::max<int64_t>(1, int64_t(gs.size()))))
                           : opt.light_samples;
  } else {
    fg.coverage.assign(size_t(HW), 0.0f);
    fg.depth.assign(size_t(HW), 0.0f);
    fg.silhouette.assign(size_t(HW), 0.0f);
    out.stats.image_pixels_total = HW;
  }
  const int64_t fg_rays = int64_t(gs.size()) * fg.light_samples;
  if (!bvh.empty()) {
    rays.resize(fg_rays);
    trace_foreground(opt, bvh, env_map, gs, fg, rays);
    QueryRays shadow_rays;  // appended after the light rays
    trace_shadows(in, opt, bvh.bounds(), bvh, env_map, depth, sh, shadow_rays, out.stats);
    rays.origin.insert(rays.origin.end(), shadow_rays.origin.begin(), shadow_rays.origin.end());
    rays.dir.insert(rays.dir.end(), shadow_rays.dir.begin(), shadow_rays.dir.end());
  } else {
    fg.offsets = {0};
    sh.texel_depth.assign(size_t(opt.shadow_width) * opt.shadow_height, 0.0f);
    sh.offsets = {0};
    out.stats.shadow_pixels_total = int64_t(opt.shadow_width) * opt.shadow_height;
  }
  const int64_t sh_rays = rays.size() - fg_rays;
  out.stats.query_rays = rays.size();

  // ---- one radiance query for every light and shadow ray (Eq. 1)
  Tensor radiance = Tensor::zeros({0, 3}, dt);
  if (rays.size() > 0 && in.vsg.defined() && opt.radiance_cache) {
    const RadianceCache cache(in, opt, env_map, rays);
    std::vector<float> l(size_t(3 * rays.size()));
    parallel_for(rays.size(), 256, [&](int64_t b, int64_t e) {
      for (int64_t r = b; r < e; ++r) {
        const glm::vec3 v = cache.radiance(&rays.origin[size_t(3 * r)], &rays.dir[size_t(3 * r)]);
        for (int c = 0; c < 3; ++c) l[size_t(3 * r + c)] = v[c];
      }
    });
    radiance = as_tensor(l, {rays.size(), 3}, dt);
  } else if (rays.size() > 0) {
    const Tensor o = as_tensor(rays.origin, {rays.size(), 3}, dt), d = as_tensor(rays.dir, {rays.size(), 3}, dt);
    radiance = in.vsg.defined() ? radiance_query(in.vsg, in.env, o, d, in.grid, opt.query).radiance : env_lookup(in.env, d);
  }

  // ---- foreground: C = Σ w·L per pixel (Eq. 2), scattered into the image
  Tensor colour = Tensor::zeros({HW, 3}, dt);
  if (!fg.pixels.empty()) {
    const Tensor per_pixel = weighted_segment_sum(slice(radiance, 0, 0, fg_rays),
                                                  as_tensor(fg.weights, {fg_rays, 3}, dt), fg.offsets);
    std::vector<int64_t> idx;
    for (int64_t p : fg.pixels) idx.insert(idx.end(), {p, p, p});
    colour = scatter_add(colour, 0, Tensor::from_indices(idx, {int64_t(fg.pixels.size()), 3}), per_pixel);
  }

  // ---- shadows: S per computed texel (Eq. 4), 1 elsewhere, upsampled edge-aware
  const int64_t n_texels = int64_t(opt.shadow_width) * opt.shadow_height;
  Tensor s_map = Tensor::ones({n_texels + 1, 3}, dt);  // the extra row is the constant 1
  if (!sh.texels.empty()) {
    // Guard of Eq. 4: S = (Σ L' + ε)/(Σ L + ε), ε = 1e-6 · mean sky radiance (never 0/0).
    const double eps = 1e-6 * std::max(1e-12, mean(in.env.detach().to(DType::F64)).item());
    const Tensor s = shadow_ratio(slice(radiance, 0, fg_rays, fg_rays + sh_rays), sh.weights, sh.visibility, sh.offsets, eps);
    std::vector<int64_t> idx;
    for (int64_t t : sh.texels) idx.insert(idx.end(), {t, t, t});
    s_map = scatter_add(s_map, 0, Tensor::from_indices(idx, {int64_t(sh.texels.size()), 3}), add_scalar(s, -1.0));
  }
  std::vector<int64_t> tap_idx;
  std::vector<double> tap_w;
  upsample_taps(in, opt, sh, depth, tap_idx, tap_w);
  const Tensor taps = index_select(s_map, 0, Tensor::from_indices(tap_idx, {HW * 4}));
  const Tensor tap_weights = Tensor::from_vector(tap_w, {HW * 4, 1}, dt);
  const Tensor s_img = sum(reshape(mul(taps, tap_weights), {HW, 4, 3}), {1});  // [HW, 3]

  // ---- composite: I_edit = α·I_obj + (1 − α)·(S ⊙ I); α·I_obj is `colour` (coverage-weighted)
  const Tensor alpha = as_tensor(fg.coverage, {HW, 1}, dt);
  const Tensor background = reshape(permute(in.background.detach().to(dt), {1, 2, 0}), {HW, 3});
  const Tensor composite = add(colour, mul(rsub_scalar(1.0, alpha), mul(s_img, background)));
  out.composite = reshape(permute(reshape(composite, {H, W, 3}), {2, 0, 1}), {3, H, W});
  out.shadow_map = reshape(permute(reshape(s_img, {H, W, 3}), {2, 0, 1}), {3, H, W});
  out.object_mask = reshape(alpha, {1, H, W});
  out.object_depth = as_tensor(fg.depth, {1, H, W}, dt);
  out.object_silhouette = as_tensor(fg.silhouette, {1, H, W}, dt);
  return out;
}

}  // namespace sl
