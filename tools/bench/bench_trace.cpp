// streetlight-bench trace | gen-rays | gen-mesh: ray-tracing throughput of render/bvh.
//
// RAYS.bin: raw little-endian float32, 6 per ray (ox oy oz dx dy dz) in the mesh's world frame
// (after node transforms), no header. HITS.bin: one float32 per ray, the closest hit distance
// (in units of the ray's direction length) or +inf on a miss. Rays span t in [0, +inf).
// tools/compare/embree_trace.cpp reads and writes the same formats.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "render/bvh.h"
#include "render/gltf_loader.h"
#include "render/gltf_writer.h"
#include "render/ray_file.h"
#include "tools/bench/bench.h"
#include "tools/bench/procedural_mesh.h"
#include "tools/common/cli.h"
#include "util/error.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"
#include "util/file.h"

using sl::render::Bounds3;
using sl::render::Bvh;
using sl::render::Hit;
using sl::render::load_gltf;
using sl::render::Mesh;
using sl::render::Ray;
using sl::render::read_ray_file;
using sl::render::write_glb;

namespace sl::bench {
namespace {

// "--key value" options and "--flag" switches; anything else is an error naming it.
struct Options {
  std::map<std::string, std::string> values;
  std::map<std::string, bool> flags;

  Options(const std::string& command, const std::vector<std::string>& args, const std::vector<std::string>& keys,
          const std::vector<std::string>& switches) {
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (std::find(switches.begin(), switches.end(), a) != switches.end()) {
        flags[a] = true;
      } else if (std::find(keys.begin(), keys.end(), a) != keys.end()) {
        SL_CHECK(i + 1 < args.size(), command, ": ", a, " needs a value");
        values[a] = args[++i];
      } else {
        fail(command, ": unknown argument '", a, "' (try ", command, " --help)");
      }
    }
  }
  bool has(const std::string& k) const { return values.count(k) > 0; }
  bool flag(const std::string& k) const { return flags.count(k) > 0; }
  std::string get(const std::string& command, const std::string& k) const {
    auto it = values.find(k);
    SL_CHECK(it != values.end(), command, ": missing required ", k);
    return it->second;
  }
  int64_t integer(const std::string& command, const std::string& k, int64_t lo, int64_t hi) const {
    return cli::parse_integer(command + ": " + k, get(command, k), lo, hi);
  }
};

bool wants_help(const std::vector<std::string>& args) {
  for (const auto& a : args)
    if (a == "--help" || a == "-h") return true;
  return false;
}


Mesh load_mesh(const std::string& command, const std::string& path) {
  Mesh m = load_gltf(path);
  SL_CHECK(m.triangle_count() > 0, command, ": --mesh '", path, "' has no triangles");
  return m;
}

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int run_trace(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::printf(
        "usage: streetlight-bench trace --mesh FILE.glb --rays RAYS.bin [--hits-out HITS.bin] [--json]\n"
        "                               [--split-budget B]\n"
        "  Builds the BVH of the mesh, then traces every ray closest-hit and any-hit (t in [0, inf)),\n"
        "  best of 5 passes each, on OMP_NUM_THREADS threads. RAYS.bin: float32 ox oy oz dx dy dz per\n"
        "  ray, world frame. HITS.bin: float32 closest hit distance per ray, +inf on a miss.\n"
        "  --split-budget B: BVH pre-split references as a share of the triangles (default: the\n"
        "  library's, render/bvh.h BvhBuildOptions; 0 turns pre-splits off).\n");
    return 0;
  }
  const Options o("trace", args, {"--mesh", "--rays", "--hits-out", "--split-budget"}, {"--json"});
  sl::render::BvhBuildOptions build_options = Bvh::default_options();
  if (o.has("--split-budget"))
  {
    const std::string v = o.get("trace", "--split-budget");
    char* end = nullptr;
    const double b = std::strtod(v.c_str(), &end);
    SL_CHECK(!v.empty() && end == v.c_str() + v.size() && b >= 0.0 && b <= 16.0,
             "trace: --split-budget must be a number in [0, 16], got '", v, "'");
    build_options.split_budget = static_cast<float>(b);
  }
  const std::string mesh_path = o.get("trace", "--mesh"), rays_path = o.get("trace", "--rays");
  const Mesh mesh = load_mesh("trace", mesh_path);
  const std::vector<Ray> rays = read_ray_file(rays_path, "trace: --rays");

  const double t0 = now_ms();
  const Bvh bvh(mesh, build_options);
  const double build_ms = now_ms() - t0;

  std::vector<Hit> hits(rays.size());
  std::vector<uint8_t> occluded(rays.size());
  double best_closest = 1e300, best_any = 1e300;
  for (int pass = 0; pass < 5; ++pass) {
    const double a = now_ms();
    bvh.intersect(rays.data(), hits.data(), rays.size());
    best_closest = std::min(best_closest, now_ms() - a);
  }
  for (int pass = 0; pass < 5; ++pass) {
    const double a = now_ms();
    bvh.occluded(rays.data(), occluded.data(), rays.size());
    best_any = std::min(best_any, now_ms() - a);
  }
  int64_t hit_count = 0, occluded_count = 0;
  for (size_t i = 0; i < rays.size(); ++i) hit_count += hits[i].hit(), occluded_count += occluded[i];
  if (o.has("--hits-out")) {
    std::vector<float> t(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) t[i] = hits[i].hit() ? hits[i].t : std::numeric_limits<float>::infinity();
    write_file_atomic(o.get("trace", "--hits-out"), std::string_view(reinterpret_cast<const char*>(t.data()), t.size() * 4));
  }
  const double n = static_cast<double>(rays.size());
  const double closest_mrays = n / (best_closest * 1e3), any_mrays = n / (best_any * 1e3);
  if (o.flag("--json")) {
    nlohmann::json j = {{"command", "trace"},          {"mesh", mesh_path},
                        {"rays_file", rays_path},      {"triangles", mesh.triangle_count()},
                        {"rays", rays.size()},         {"threads", omp_get_max_threads()},
                        {"bvh_nodes", bvh.node_count()}, {"bvh_depth", bvh.depth()},
                        {"bvh_references", bvh.reference_count()}, {"split_budget", build_options.split_budget},
                        {"build_ms", build_ms},        {"closest_mrays_per_s", closest_mrays},
                        {"any_mrays_per_s", any_mrays}, {"hits", hit_count},
                        {"occluded", occluded_count}};
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("mesh %s: %zu triangles, %zu rays, %d threads\n", mesh_path.c_str(), mesh.triangle_count(),
                rays.size(), omp_get_max_threads());
    std::printf("  build      %10.2f ms (%zu nodes, depth %d)\n", build_ms, bvh.node_count(), bvh.depth());
    std::printf("  closest    %10.2f Mrays/s  (%lld hits)\n", closest_mrays, static_cast<long long>(hit_count));
    std::printf("  any-hit    %10.2f Mrays/s  (%lld occluded)\n", any_mrays, static_cast<long long>(occluded_count));
  }
  return 0;
}

// Unit vector uniform on the sphere from two counters of (seed, ray).
glm::vec3 uniform_direction(uint64_t seed, uint64_t ray) {
  const float z = 1.0f - 2.0f * uniform01f(seed, ray, 3);
  const float phi = (2.0f * kPiF) * uniform01f(seed, ray, 4);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

int run_gen_rays(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::printf(
        "usage: streetlight-bench gen-rays --mesh FILE.glb --kind primary|random --count N --seed S --out RAYS.bin\n"
        "  primary: pinhole camera rays from outside the mesh's bounding box, aimed at its centre,\n"
        "           one jittered ray per pixel of a near-square image of N pixels.\n"
        "  random:  origins uniform in the bounding box scaled 1.5x about its centre, directions\n"
        "           uniform on the sphere. Counter-based: (seed, ray index) decides each ray.\n");
    return 0;
  }
  const char* cmd = "gen-rays";
  const Options o(cmd, args, {"--mesh", "--kind", "--count", "--seed", "--out"}, {});
  const std::string kind = o.get(cmd, "--kind");
  SL_CHECK(kind == "primary" || kind == "random", cmd, ": --kind must be primary or random, got '", kind, "'");
  const int64_t count = o.integer(cmd, "--count", 1, int64_t{1} << 30);
  const uint64_t seed = static_cast<uint64_t>(o.integer(cmd, "--seed", 0, INT64_MAX));
  const std::string out = o.get(cmd, "--out");
  const Mesh mesh = load_mesh(cmd, o.get(cmd, "--mesh"));
  const Bounds3 box = mesh.bounds();
  const glm::vec3 centre = box.centre(), extent = box.extent();
  std::vector<float> data(static_cast<size_t>(count) * 6);

  if (kind == "random") {
    parallel_for(count, 4096, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        const glm::vec3 u(uniform01f(seed, i, 0), uniform01f(seed, i, 1), uniform01f(seed, i, 2));
        const glm::vec3 origin = centre + 1.5f * extent * (u - 0.5f);
        const glm::vec3 d = uniform_direction(seed, static_cast<uint64_t>(i));
        float* p = &data[6 * i];
        p[0] = origin.x, p[1] = origin.y, p[2] = origin.z, p[3] = d.x, p[4] = d.y, p[5] = d.z;
      }
    });
  } else {
    // Look-at camera on the bounding sphere's outside, from above and to the side; the vertical
    // field of view just contains the sphere.
    const float radius = std::max(0.5f * glm::length(extent), 1e-6f);
    const glm::vec3 view_dir = glm::normalize(glm::vec3(0.8f, 0.5f, 1.2f));
    const float distance = 2.5f * radius;
    const glm::vec3 eye = centre + distance * view_dir;
    const glm::vec3 forward = -view_dir;
    const glm::vec3 right = glm::normalize(glm::cross(forward, glm::vec3(0.0f, 1.0f, 0.0f)));
    const glm::vec3 down = glm::cross(forward, right);  // camera y points down (OpenCV frame)
    const float tan_half = std::tan(std::asin(radius / distance));
    const int64_t width = static_cast<int64_t>(std::ceil(std::sqrt(static_cast<double>(count))));
    const int64_t height = (count + width - 1) / width;
    const float scale = 2.0f * tan_half / static_cast<float>(std::max(width, height));
    parallel_for(count, 4096, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        const float px = static_cast<float>(i % width) + uniform01f(seed, i, 0);
        const float py = static_cast<float>(i / width) + uniform01f(seed, i, 1);
        const float x = (px - 0.5f * width) * scale, y = (py - 0.5f * height) * scale;
        const glm::vec3 d = glm::normalize(forward + x * right + y * down);
        float* p = &data[6 * i];
        p[0] = eye.x, p[1] = eye.y, p[2] = eye.z, p[3] = d.x, p[4] = d.y, p[5] = d.z;
      }
    });
  }
  write_file_atomic(out, std::string_view(reinterpret_cast<const char*>(data.data()), data.size() * 4));
  std::fprintf(stderr, "gen-rays: wrote %lld %s rays to %s\n", static_cast<long long>(count), kind.c_str(),
               out.c_str());
  return 0;
}

// A closed, bumpy sphere of radius about 2 m: a UV sphere whose radius is modulated by a few
// fixed sinusoids, so it has concavities, silhouettes and a wide spread of triangle sizes.
Mesh displaced_sphere(int64_t min_triangles) {
  // A UV sphere with `bands` latitude bands and 2·bands segments has 4·bands·(bands - 1) triangles.
  const int64_t bands =
      std::max<int64_t>(2, static_cast<int64_t>(std::ceil(0.5 * (1.0 + std::sqrt(1.0 + min_triangles)))));
  const int64_t segments = 2 * bands;
  Mesh m;
  auto radius = [](float theta, float phi) {
    return 2.0f * (1.0f + 0.12f * std::sin(5.0f * theta) * std::cos(7.0f * phi) +
                   0.05f * std::sin(23.0f * theta + 1.0f) * std::sin(19.0f * phi) +
                   0.02f * std::cos(61.0f * theta) * std::sin(53.0f * phi + 2.0f));
  };
  const float pi = kPiF;
  m.positions.push_back({0.0f, radius(0.0f, 0.0f), 0.0f});
  for (int64_t i = 1; i < bands; ++i) {
    const float theta = pi * static_cast<float>(i) / bands;
    for (int64_t j = 0; j < segments; ++j) {
      const float phi = 2.0f * pi * static_cast<float>(j) / segments;
      const float r = radius(theta, phi);
      m.positions.push_back({r * std::sin(theta) * std::cos(phi), r * std::cos(theta), -r * std::sin(theta) * std::sin(phi)});
    }
  }
  m.positions.push_back({0.0f, -radius(pi, 0.0f), 0.0f});
  const uint32_t south = static_cast<uint32_t>(m.positions.size() - 1);
  auto ring = [&](int64_t i, int64_t j) { return static_cast<uint32_t>(1 + (i - 1) * segments + (j % segments)); };
  for (int64_t j = 0; j < segments; ++j) {
    m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
    for (int64_t i = 1; i + 1 < bands; ++i) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
    m.triangles.push_back({ring(bands - 1, j), south, ring(bands - 1, j + 1)});
  }
  m.materials.resize(1);
  m.materials[0].name = "bumpy";
  m.materials[0].base_color_factor = glm::vec4(0.6f, 0.6f, 0.6f, 1.0f);
  m.materials[0].metallic = 0.0f;
  m.materials[0].roughness = 0.5f;
  m.material_ids.assign(m.triangles.size(), 0);
  m.compute_vertex_normals();
  return m;
}

int run_gen_mesh(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::printf(
        "usage: streetlight-bench gen-mesh --triangles N --out FILE.glb [--kind KIND] [--seed S]\n"
        "  Writes a procedural mesh with at least N triangles (a few percent more at most for the\n"
        "  part-based kinds). Deterministic: the same (kind, N, seed) give the same file. KIND:\n"
        "    sphere   (default) displaced UV sphere, radius about 2 m; ignores --seed\n"
        "    machine  CAD-like: hundreds of small disjoint boxes, cylinders, tubes, bolt rings\n"
        "    facade   street blocks of buildings: thin walls, windows, frames, balconies, ground\n"
        "    blob     organic, scan-like: noise-displaced cube sphere, near-uniform triangles\n"
        "    foliage  thin randomly oriented overlapping slivers in tree crowns, ground plane\n"
        "    terrain  fractal heightfield, 1 km square\n"
        "  --seed S: 0..2^63-1, default 1.\n");
    return 0;
  }
  const char* cmd = "gen-mesh";
  const Options o(cmd, args, {"--triangles", "--out", "--kind", "--seed"}, {});
  const int64_t n = o.integer(cmd, "--triangles", 1, 100'000'000);
  const std::string out = o.get(cmd, "--out");
  const std::string kind = o.has("--kind") ? o.get(cmd, "--kind") : "sphere";
  const uint64_t seed = o.has("--seed") ? static_cast<uint64_t>(o.integer(cmd, "--seed", 0, INT64_MAX)) : 1;
  const auto& kinds = procedural_mesh_kinds();
  SL_CHECK(kind == "sphere" || std::find(kinds.begin(), kinds.end(), kind) != kinds.end(), cmd,
           ": --kind must be sphere, machine, facade, blob, foliage or terrain, got '", kind, "'");
  const Mesh m = kind == "sphere" ? displaced_sphere(n) : procedural_mesh(kind, n, seed);
  write_glb(m, out);
  std::fprintf(stderr, "gen-mesh: wrote %zu triangles (%s) to %s\n", m.triangle_count(), kind.c_str(), out.c_str());
  return 0;
}

Registrar reg_trace("trace", "BVH closest-hit and any-hit throughput on a mesh and a ray file", &run_trace);
Registrar reg_gen_rays("gen-rays", "write primary or random rays for a mesh (RAYS.bin)", &run_gen_rays);
Registrar reg_gen_mesh("gen-mesh", "write a procedural mesh with at least N triangles (.glb)", &run_gen_mesh);

}  // namespace
}  // namespace sl::bench
