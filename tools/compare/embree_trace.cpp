// streetlight-embree-trace: the Embree 3 anchor for `streetlight-bench trace` (docs/DESIGN.md, "Anchors").
// Optional and never linked into the library. Same inputs and outputs as bench trace:
// RAYS.bin (float32 ox oy oz dx dy dz per ray, t in [0, inf)), HITS.bin (float32 closest t or
// +inf). rtcIntersect1 / rtcOccluded1 in an OpenMP loop on OMP_NUM_THREADS threads, best of 5.
#include <embree3/rtcore.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "render/gltf_loader.h"
#include "util/error.h"
#include "util/file.h"

namespace {

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::vector<float> read_rays(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  SL_CHECK(in.good(), "cannot open --rays '", path, "'");
  const std::streamoff size = in.tellg();
  SL_CHECK(size > 0 && size % 24 == 0, "--rays '", path, "' has ", size, " bytes, expected a positive multiple of 24");
  std::vector<float> raw(static_cast<size_t>(size) / 4);
  in.seekg(0);
  in.read(reinterpret_cast<char*>(raw.data()), size);
  SL_CHECK(in.good(), "cannot read --rays '", path, "'");
  return raw;
}

void write_atomically(const std::string& path, const std::vector<float>& v) {
  sl::write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * 4));
}

RTCRayHit make_ray(const float* p) {
  RTCRayHit rh;
  rh.ray.org_x = p[0], rh.ray.org_y = p[1], rh.ray.org_z = p[2];
  rh.ray.dir_x = p[3], rh.ray.dir_y = p[4], rh.ray.dir_z = p[5];
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

int run(int argc, char** argv) {
  std::string mesh_path, rays_path, hits_path;
  bool json = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::printf("usage: streetlight-embree-trace --mesh FILE.glb --rays RAYS.bin [--hits-out HITS.bin] [--json]\n");
      return 0;
    } else if (a == "--json") {
      json = true;
    } else if ((a == "--mesh" || a == "--rays" || a == "--hits-out") && i + 1 < argc) {
      (a == "--mesh" ? mesh_path : a == "--rays" ? rays_path : hits_path) = argv[++i];
    } else {
      sl::fail("unknown or incomplete argument '", a, "'");
    }
  }
  SL_CHECK(!mesh_path.empty() && !rays_path.empty(), "--mesh and --rays are required");
  const sl::render::Mesh mesh = sl::render::load_gltf(mesh_path);
  const std::vector<float> raw = read_rays(rays_path);
  const size_t n = raw.size() / 6;

  RTCDevice device = rtcNewDevice(nullptr);
  SL_CHECK(device, "rtcNewDevice failed");
  const double t0 = now_ms();
  RTCScene scene = rtcNewScene(device);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                         3 * sizeof(float), mesh.positions.size()));
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    vb[3 * i] = mesh.positions[i].x, vb[3 * i + 1] = mesh.positions[i].y, vb[3 * i + 2] = mesh.positions[i].z;
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(unsigned), mesh.triangles.size()));
  for (size_t t = 0; t < mesh.triangles.size(); ++t)
    ib[3 * t] = mesh.triangles[t].x, ib[3 * t + 1] = mesh.triangles[t].y, ib[3 * t + 2] = mesh.triangles[t].z;
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  const double build_ms = now_ms() - t0;

  std::vector<float> tfar(n);
  std::vector<uint8_t> occ(n);
  const int64_t count = static_cast<int64_t>(n);
  double best_closest = 1e300, best_any = 1e300;
  for (int pass = 0; pass < 5; ++pass) {
    const double a = now_ms();
#pragma omp parallel
    {
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
#pragma omp for schedule(dynamic, 64)
      for (int64_t i = 0; i < count; ++i) {
        RTCRayHit rh = make_ray(&raw[6 * i]);
        rtcIntersect1(scene, &ctx, &rh);
        tfar[i] = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID ? rh.ray.tfar : std::numeric_limits<float>::infinity();
      }
    }
    best_closest = std::min(best_closest, now_ms() - a);
  }
  for (int pass = 0; pass < 5; ++pass) {
    const double a = now_ms();
#pragma omp parallel
    {
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
#pragma omp for schedule(dynamic, 64)
      for (int64_t i = 0; i < count; ++i) {
        RTCRayHit rh = make_ray(&raw[6 * i]);
        rtcOccluded1(scene, &ctx, &rh.ray);
        occ[i] = rh.ray.tfar < 0.0f;  // Embree marks an occluded ray with tfar = -inf
      }
    }
    best_any = std::min(best_any, now_ms() - a);
  }
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);

  int64_t hits = 0, occluded = 0;
  for (size_t i = 0; i < n; ++i) hits += std::isfinite(tfar[i]), occluded += occ[i];
  if (!hits_path.empty()) write_atomically(hits_path, tfar);
  const double closest = n / (best_closest * 1e3), any = n / (best_any * 1e3);
  if (json) {
    nlohmann::json j = {{"command", "embree-trace"}, {"mesh", mesh_path}, {"rays_file", rays_path},
                        {"triangles", mesh.triangle_count()}, {"rays", n}, {"threads", omp_get_max_threads()},
                        {"build_ms", build_ms}, {"closest_mrays_per_s", closest}, {"any_mrays_per_s", any},
                        {"hits", hits}, {"occluded", occluded}};
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("embree %s: %zu triangles, %zu rays, build %.2f ms, closest %.2f Mrays/s (%lld hits), any %.2f Mrays/s\n",
                mesh_path.c_str(), mesh.triangle_count(), n, build_ms, closest, static_cast<long long>(hits), any);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const sl::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
