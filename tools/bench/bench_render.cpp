// streetlight-bench render: error against time of the reference path tracer (render/path_tracer.h)
// as samples per pixel grow, with and without environment importance sampling (NEE + MIS).
//
// Scene: a glTF model (default CesiumMilkTruck) standing on a grey ground plane under an HDRI,
// seen from a fixed three-quarter view. The reference is the same renderer at --ref-spp with a
// different seed, so the RMSE measures noise (both estimators are unbiased). Writes
// OUT/render_bench.csv (method, spp, time_ms, rmse), OUT/render_bench.png (log-log RMSE against
// time: blue = environment sampling + MIS, red = BRDF sampling only) and OUT/render_reference.exr.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "autodiff/error.h"
#include "data/image_io.h"
#include "render/camera.h"
#include "render/environment_map.h"
#include "render/gltf_loader.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "tools/bench/bench.h"
#include "tools/bench/timing.h"
#include "tools/common/plot.h"

namespace sl::bench {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Shared data folder: $STREETLIGHT_DATA, else ../shared/data (the checkout's sibling, as in tests).
std::string data_root() {
  const char* env = std::getenv("STREETLIGHT_DATA");
  return env && *env ? env : "../shared/data";
}

struct Args {
  std::string model = data_root() + "/models/CesiumMilkTruck.glb";
  std::string hdri = data_root() + "/hdri/kloppenheim_05_1k.hdr";
  std::string out = ".";
  int width = 160, height = 90, ref_spp = 1024, max_spp = 256, max_depth = 6;
  bool json = false;
};

int to_int(const std::string& key, const std::string& v, int lo, int hi) {
  size_t used = 0;
  long long x = 0;
  try {
    x = std::stoll(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  SL_CHECK(used == v.size() && !v.empty() && x >= lo && x <= hi, "render: ", key, " must be an integer in [", lo, ", ",
           hi, "], got '", v, "'");
  return static_cast<int>(x);
}

Args parse(const std::vector<std::string>& a) {
  Args r;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i] == "--json") {
      r.json = true;
      continue;
    }
    SL_CHECK(i + 1 < a.size(), "render: ", a[i], " needs a value (try render --help)");
    const std::string& k = a[i];
    const std::string& v = a[++i];
    if (k == "--model") r.model = v;
    else if (k == "--hdri") r.hdri = v;
    else if (k == "--out") r.out = v;
    else if (k == "--width") r.width = to_int(k, v, 8, 4096);
    else if (k == "--height") r.height = to_int(k, v, 8, 4096);
    else if (k == "--ref-spp") r.ref_spp = to_int(k, v, 1, 1 << 16);
    else if (k == "--max-spp") r.max_spp = to_int(k, v, 1, 1 << 14);
    else if (k == "--max-depth") r.max_depth = to_int(k, v, 1, 64);
    else fail("render: unknown argument '", k, "' (try render --help)");
  }
  return r;
}

// The model standing on y = 0 (its lowest point) on a 60 m grey ground square.
Mesh build_scene(const std::string& model_path, Bounds3& model_bounds) {
  Mesh model = load_gltf(model_path);
  SL_CHECK(model.triangle_count() > 0, "render: --model '", model_path, "' has no triangles");
  const Bounds3 b = model.bounds();
  for (glm::vec3& p : model.positions) p.y -= b.lo.y;
  model_bounds = model.bounds();
  Material ground;
  ground.name = "ground";
  ground.base_color_factor = glm::vec4(0.3f, 0.3f, 0.3f, 1.0f);
  ground.metallic = 0.0f;
  ground.roughness = 0.9f;
  model.append(make_ground_plane(60.0f, 0.0f, ground, model_bounds.centre().x, model_bounds.centre().z));
  return model;
}

Camera three_quarter_view(const Bounds3& b, int width, int height) {
  const glm::dvec3 c(b.centre());
  const double r = 0.5 * glm::length(glm::dvec3(b.extent()));
  const glm::dvec3 pos = c + r * glm::dvec3(1.8, 0.9, 2.2);
  const glm::dvec3 f = glm::normalize(c - pos);
  const double yaw = std::atan2(f.x, -f.z), pitch = std::asin(f.y);
  return Camera(intrinsics_from_fov(50.0 * kPi / 180.0, width, height), rotation_from_yaw_pitch_roll(yaw, pitch, 0.0),
                pos);
}

struct Point {
  std::string method;
  int spp;
  double time_ms, rmse;
};

double rmse(const Tensor& a, const Tensor& b) {
  const float *pa = a.data<float>(), *pb = b.data<float>();
  double s = 0.0;
  for (int64_t i = 0; i < a.numel(); ++i) s += double(pa[i] - pb[i]) * double(pa[i] - pb[i]);
  return std::sqrt(s / double(a.numel()));
}

int run_render(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench render [--model FILE.glb] [--hdri FILE.hdr] [--out DIR] [--width W]\n"
          "         [--height H] [--ref-spp N] [--max-spp N] [--max-depth D] [--json]\n"
          "  Path-traces the model on a ground plane under the HDRI at 1, 2, 4, ... --max-spp samples\n"
          "  per pixel, with environment importance sampling + MIS (env_mis) and with BRDF sampling only\n"
          "  (brdf_only), and reports (time, RMSE against a --ref-spp reference). Writes\n"
          "  DIR/render_bench.csv, DIR/render_bench.png (log-log RMSE vs time in ms; blue env_mis, red\n"
          "  brdf_only) and DIR/render_reference.exr. Defaults: CesiumMilkTruck.glb and\n"
          "  kloppenheim_05_1k.hdr from $STREETLIGHT_DATA (else ../shared/data), 160x90, reference\n"
          "  1024 spp, sweep to 256 spp, depth 6.\n");
      return 0;
    }
  const Args args = parse(argv);
  SL_CHECK(args.ref_spp >= args.max_spp, "render: --ref-spp (", args.ref_spp, ") must be >= --max-spp (",
           args.max_spp, ")");
  Bounds3 model_bounds;
  const Mesh scene = build_scene(args.model, model_bounds);
  ImageReadOptions ro;
  ro.channels = 3;
  const EnvironmentMap env(read_image(args.hdri, ro));
  const Camera camera = three_quarter_view(model_bounds, args.width, args.height);
  const PathTracer tracer(scene, env);
  std::fprintf(stderr, "render: %zu triangles, HDRI %dx%d, %dx%d pixels, %d threads\n", scene.triangle_count(),
               env.width(), env.height(), args.width, args.height, omp_get_max_threads());

  PathTracerOptions o;
  o.max_depth = args.max_depth;
  o.spp = args.ref_spp;
  o.seed = 1000003;
  std::fprintf(stderr, "render: reference at %d spp...\n", args.ref_spp);
  const double t_ref = now_ms();
  const PathTracerImage ref = tracer.render(camera, o);
  std::fprintf(stderr, "render: reference took %.1f s\n", (now_ms() - t_ref) / 1000.0);

  std::vector<Point> pts;
  for (const bool env_sampling : {true, false})
    for (int spp = 1; spp <= args.max_spp; spp *= 2) {
      o.spp = spp;
      o.seed = 1;
      o.environment_sampling = env_sampling;
      const double t0 = now_ms();
      const PathTracerImage img = tracer.render(camera, o);
      const Point p{env_sampling ? "env_mis" : "brdf_only", spp, now_ms() - t0, rmse(img.radiance, ref.radiance)};
      pts.push_back(p);
      if (args.json)
        std::printf("{\"bench\":\"render\",\"method\":\"%s\",\"spp\":%d,\"time_ms\":%.3f,\"rmse\":%.6g}\n",
                    p.method.c_str(), p.spp, p.time_ms, p.rmse);
      else
        std::printf("%-10s spp %5d  time %9.1f ms  rmse %.5g\n", p.method.c_str(), p.spp, p.time_ms, p.rmse);
      std::fflush(stdout);
    }

  std::filesystem::create_directories(args.out);
  const std::string csv = args.out + "/render_bench.csv", tmp = csv + ".tmp";
  {
    std::ofstream f(tmp, std::ios::trunc);
    SL_CHECK(f.good(), "render: cannot write '", tmp, "'");
    f << "method,spp,time_ms,rmse\n";
    for (const Point& p : pts) f << p.method << ',' << p.spp << ',' << p.time_ms << ',' << p.rmse << '\n';
    SL_CHECK(f.good(), "render: failed writing '", tmp, "'");
  }
  SL_CHECK(std::rename(tmp.c_str(), csv.c_str()) == 0, "render: cannot rename '", tmp, "' to '", csv, "'");
  ImageWriteOptions wo;
  wo.transfer = Transfer::Linear;  // the plot's colours are display values already
  std::vector<cli::PlotPoint> plot_points;
  for (const Point& p : pts) plot_points.push_back({p.method, p.time_ms, p.rmse});
  write_image(args.out + "/render_bench.png", cli::error_time_plot(plot_points), wo);
  write_image(args.out + "/render_reference.exr", ref.radiance);
  std::fprintf(stderr, "render: wrote %s, render_bench.png, render_reference.exr\n", csv.c_str());
  return 0;
}

Registrar reg_render("render", "path tracer RMSE vs time, with and without environment importance sampling",
                     &run_render);

}  // namespace
}  // namespace sl::bench
