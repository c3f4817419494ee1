// Reference path tracer: the per-path integrator (NEE + MIS, Russian roulette) over the BVH.
// The per-pixel image loop lives in path_tracer_image.cpp (it needs render/camera.h, whose
// sl::render::Ray clashes with render/bvh.h's sl::render::Ray in one translation unit).
#include "render/path_tracer.h"

#include <cmath>

#include "render/bvh.h"
#include "render/disney_brdf.h"
#include "render/qmc_sampler.h"
#include "render/sampling.h"
#include "util/error.h"
#include "util/random.h"

namespace sl::render {

struct PathTracer::Scene {
  const Mesh& mesh;
  const EnvironmentMap& env;
  Bvh bvh;
  std::vector<glm::vec3> face_normals;  // unit geometric normals (zero for degenerate faces)

  Scene(const Mesh& m, const EnvironmentMap& e) : mesh(m), env(e), bvh(m) {
    face_normals.reserve(m.triangles.size());
    for (const glm::uvec3& t : m.triangles)
      face_normals.push_back(safe_normalize(
          glm::cross(m.positions[t.y] - m.positions[t.x], m.positions[t.z] - m.positions[t.x])));
  }
};

namespace {

// A shading point with both normals flipped to face the outgoing direction (two-sided surfaces).
struct SurfacePoint {
  glm::vec3 p, ng, ns;
  glm::vec2 uv{0.0f};
  uint32_t triangle = 0;
};

SurfacePoint surface_point(const Mesh& mesh, const std::vector<glm::vec3>& face_normals, const Hit& hit,
                           const glm::vec3& wo) {
  SurfacePoint s;
  const glm::uvec3 t = mesh.triangles[hit.triangle];
  const float w = 1.0f - hit.u - hit.v;
  s.triangle = hit.triangle;
  s.p = w * mesh.positions[t.x] + hit.u * mesh.positions[t.y] + hit.v * mesh.positions[t.z];
  s.ng = face_normals[hit.triangle];
  s.ns = mesh.normals.empty()
             ? s.ng
             : safe_normalize(w * mesh.normals[t.x] + hit.u * mesh.normals[t.y] + hit.v * mesh.normals[t.z]);
  if (glm::dot(s.ns, s.ns) == 0.0f) s.ns = s.ng;
  if (glm::dot(s.ng, wo) < 0.0f) {
    s.ng = -s.ng;
    s.ns = -s.ns;
  }
  // Interpolated normals can lean past the view; the BRDF would then see wo below its horizon.
  if (glm::dot(s.ns, wo) <= 0.0f) s.ns = s.ng;
  if (!mesh.uvs.empty()) s.uv = w * mesh.uvs[t.x] + hit.u * mesh.uvs[t.y] + hit.v * mesh.uvs[t.z];
  return s;
}

// The material at a shading point: Disney, or Lambertian for the analytic validation scenes.
struct Bsdf {
  disney::Params params;
  bool lambertian = false;

  glm::vec3 eval(const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi) const {
    if (!lambertian) return disney::eval(params, n, wo, wi);
    return glm::dot(n, wo) > 0.0f && glm::dot(n, wi) > 0.0f ? params.base_color / kPiF : glm::vec3(0.0f);
  }
  float pdf(const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi) const {
    if (!lambertian) return disney::pdf(params, n, wo, wi);
    return glm::dot(n, wo) > 0.0f ? cosine_hemisphere_pdf(glm::dot(n, wi)) : 0.0f;
  }
  disney::Sample sample(const glm::vec3& n, const glm::vec3& wo, float u1, float u2, float u3) const {
    if (!lambertian) return disney::sample(params, n, wo, u1, u2, u3);
    disney::Sample s;
    if (!(glm::dot(n, wo) > 0.0f)) return s;
    s.wi = safe_normalize(Frame(n).to_world(cosine_hemisphere(u1, u2)));
    s.pdf = cosine_hemisphere_pdf(glm::dot(n, s.wi));
    if (s.pdf > 0.0f) s.f = params.base_color / kPiF;
    return s;
  }
};

Bsdf material_at(const Mesh& mesh, const SurfacePoint& s, bool lambertian, bool exact_fresnel) {
  const Material& m = mesh.materials[mesh.material_ids[s.triangle]];
  Bsdf b;
  b.lambertian = lambertian;
  // glTF metallic-roughness on the Disney model: specular 0.5 is glTF's dielectric F0 = 0.04.
  b.params.base_color = glm::vec3(m.base_color(s.uv));
  b.params.metallic = m.metallic;
  b.params.roughness = m.roughness;
  b.params.specular = 0.5f;
  b.params.clearcoat = m.clearcoat;
  b.params.clearcoat_gloss = 1.0f - m.clearcoat_roughness;
  b.params.exact_fresnel = exact_fresnel;
  return b;
}

// A ray leaving p on the side of `side_normal` that `dir` points to. The origin is pushed off
// the surface by a distance proportional to the coordinates' magnitude, well above float
// rounding of the hit point, so the ray cannot re-hit the surface it leaves.
Ray spawn_ray(const glm::vec3& p, const glm::vec3& side_normal, const glm::vec3& dir) {
  const float scale = 1.0f + std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z)));
  Ray r;
  r.origin = p + side_normal * (1e-4f * scale);
  r.direction = dir;
  r.tmin = 0.0f;
  return r;
}

}  // namespace

PathTracer::PathTracer(const Mesh& mesh, const EnvironmentMap& environment) {
  mesh.validate("PathTracer mesh");
  SL_CHECK(environment.width() > 0 && environment.height() > 0, "PathTracer: the environment map is empty");
  scene_ = std::make_unique<Scene>(mesh, environment);
}

PathTracer::~PathTracer() = default;

void PathTracer::validate(const PathTracerOptions& o) {
  SL_CHECK(o.spp >= 1, "PathTracer: options.spp must be >= 1, got ", o.spp);
  SL_CHECK(o.max_depth >= 1 && o.max_depth <= 1024, "PathTracer: options.max_depth must be in [1, 1024], got ",
           o.max_depth);
  SL_CHECK(o.roulette_depth >= 1, "PathTracer: options.roulette_depth must be >= 1, got ", o.roulette_depth);
  SL_CHECK(o.sample_offset >= 0 && o.sample_offset + o.spp <= (int64_t(1) << 32),
           "PathTracer: options.sample_offset must be in [0, 2^32 - spp], got ", o.sample_offset);
}

// Random dimensions of one path sample: 2 for the sub-pixel position, then per bounce b the
// pairs (environment u1, u2), (BRDF u1, u2), (lobe choice, roulette) at 2 + 6b + 2·use.
namespace {
glm::vec2 path_pair(const PathTracerOptions& o, uint64_t stream, uint64_t sample, uint32_t dim) {
  if (o.estimator == PathEstimator::Independent) {
    const uint64_t c = sample * path_random::stride(o.max_depth) + dim;
    return {uniform01f(o.seed, stream, c), uniform01f(o.seed, stream, c + 1)};
  }
  return qmc::owen_pair(o.seed, stream, sample, dim / 2);
}
}  // namespace

glm::vec2 PathTracer::pixel_jitter(uint64_t stream, uint64_t sample, const PathTracerOptions& o) {
  return path_pair(o, stream, sample, 0);
}

glm::vec3 PathTracer::radiance(const glm::vec3& origin, const glm::vec3& direction, uint64_t stream,
                               uint64_t sample, const PathTracerOptions& o) const {
  const Scene& sc = *scene_;
  const bool independent = o.estimator == PathEstimator::Independent;
  auto pair = [&](int bounce, int use) {
    return path_pair(o, stream, sample,
                     static_cast<uint32_t>(path_random::kPixelDims + bounce * path_random::kBounceDims + 2 * use));
  };

  glm::vec3 L(0.0f), beta(1.0f);
  Ray ray;
  ray.origin = origin;
  ray.direction = safe_normalize(direction);
  if (glm::dot(ray.direction, ray.direction) == 0.0f) return L;
  float brdf_pdf = 0.0f;  // density of the BRDF sample that produced `ray` (0 for the camera ray)

  for (int bounce = 0;; ++bounce) {
    const Hit hit = sc.bvh.intersect(ray);
    if (!hit.hit()) {
      // Veach's MIS: a BRDF-sampled direction could also have come from the environment sampler.
      float w = 1.0f;
      if (bounce > 0 && o.environment_sampling)
        w = power_heuristic(brdf_pdf, independent ? sc.env.pdf(ray.direction) : sc.env.pdf_bilinear(ray.direction));
      L += beta * w * sc.env.lookup(ray.direction);
      break;
    }
    if (bounce >= o.max_depth) break;
    const glm::vec3 wo = -ray.direction;
    const SurfacePoint s = surface_point(sc.mesh, sc.face_normals, hit, wo);
    if (glm::dot(s.ng, s.ng) == 0.0f) break;
    const Bsdf bsdf = material_at(sc.mesh, s, o.lambertian, o.exact_fresnel);
    const glm::vec2 u_lobe_roulette = pair(bounce, 2);

    if (o.environment_sampling) {  // next-event estimation towards the environment
      const glm::vec2 u = pair(bounce, 0);
      const EnvironmentMap::Sample ls = independent ? sc.env.sample(u.x, u.y) : sc.env.sample_bilinear(u.x, u.y);
      const float cos_i = glm::dot(s.ns, ls.direction);
      if (ls.pdf > 0.0f && cos_i > 0.0f && glm::dot(s.ng, ls.direction) > 0.0f &&
          glm::dot(ls.radiance, ls.radiance) > 0.0f) {
        const glm::vec3 f = bsdf.eval(s.ns, wo, ls.direction);
        if (glm::dot(f, f) > 0.0f && !sc.bvh.occluded(spawn_ray(s.p, s.ng, ls.direction))) {
          const float w = power_heuristic(ls.pdf, bsdf.pdf(s.ns, wo, ls.direction));
          L += beta * f * ls.radiance * (cos_i * w / ls.pdf);
        }
      }
    }

    const glm::vec2 ub = pair(bounce, 1);
    const disney::Sample bs = bsdf.sample(s.ns, wo, ub.x, ub.y, u_lobe_roulette.x);
    const float cos_i = glm::dot(s.ns, bs.wi);
    if (!(bs.pdf > 0.0f) || !(cos_i > 0.0f) || !(glm::dot(s.ng, bs.wi) > 0.0f)) break;
    beta *= bs.f * (cos_i / bs.pdf);
    brdf_pdf = bs.pdf;

    if (bounce + 1 >= o.roulette_depth) {
      // Survival ∝ throughput. The old cap at 0.95 killed 5% of full-weight paths and added
      // variance at every depth; uncapped, a path is only gambled once its weight has dropped.
      const float q = std::min(independent ? 0.95f : 1.0f, std::max(beta.x, std::max(beta.y, beta.z)));
      if (!(q > 0.0f)) break;
      if (q < 1.0f) {
        if (u_lobe_roulette.y >= q) break;
        beta /= q;
      }
    }
    ray = spawn_ray(s.p, s.ng, bs.wi);
  }
  return L;
}

PathTracer::PrimaryHit PathTracer::first_hit(const glm::vec3& origin, const glm::vec3& direction) const {
  PrimaryHit out;
  Ray ray;
  ray.origin = origin;
  ray.direction = safe_normalize(direction);
  const Hit hit = scene_->bvh.intersect(ray);
  if (!hit.hit()) return out;
  const SurfacePoint s = surface_point(scene_->mesh, scene_->face_normals, hit, -ray.direction);
  out.hit = true;
  out.distance = hit.t;
  out.normal = s.ns;
  return out;
}

}  // namespace sl::render
