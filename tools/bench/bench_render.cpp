// streetlight-bench render: error against time of the reference path tracer (render/path_tracer.h)
// as samples per pixel grow, for its estimators:
//   stratified   environment importance sampling + BRDF sampling + MIS, Owen-scrambled Sobol
//                samples, uncapped roulette (the default estimator)
//   independent  the same NEE + MIS with independent random numbers and roulette capped at 0.95
//                (the original independent estimator)
//   brdf_only    BRDF sampling only, independent numbers (the older baseline)
// Scene: a glTF model (default CesiumMilkTruck) standing on a grey ground plane under each
// HDRI (default: chinese_garden = hard sun, potsdamer_platz = soft sky), seen from a fixed
// three-quarter view. The reference is the stratified estimator at --ref-spp with another
// seed, so the RMSE measures noise (all estimators are unbiased). Each point also reports the
// pixel noise from two seeds, sqrt(mean((a − b)²) / 2), and the relative noise (÷ the
// reference's mean pixel value). Writes OUT/render_bench.csv (hdri, method, spp, time_ms,
// rmse, noise, relative_noise, mean), OUT/render_bench.png (log-log RMSE against time, one
// line per hdri:method) and OUT/render_reference_<hdri>.exr.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "data/image_io.h"
#include "render/camera.h"
#include "render/environment_map.h"
#include "render/gltf_loader.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "tools/bench/bench.h"
#include "tools/bench/timing.h"
#include "tools/common/cli.h"
#include "tools/common/plot.h"
#include "util/error.h"
#include "util/file.h"
#include "util/math.h"

using sl::data::ImageReadOptions;
using sl::data::ImageWriteOptions;
using sl::data::read_image;
using sl::data::Transfer;
using sl::data::write_image;
using sl::render::Bounds3;
using sl::render::Camera;
using sl::render::EnvironmentMap;
using sl::render::intrinsics_from_fov;
using sl::render::load_gltf;
using sl::render::make_ground_plane;
using sl::render::Material;
using sl::render::Mesh;
using sl::render::PathEstimator;
using sl::render::PathTracer;
using sl::render::PathTracerImage;
using sl::render::PathTracerOptions;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::bench {
namespace {

// Shared data folder: $STREETLIGHT_DATA, else ../shared/data (the checkout's sibling, as in tests).
std::string data_root() {
  const char* env = std::getenv("STREETLIGHT_DATA");
  return env && *env ? env : "../shared/data";
}

struct Args {
  std::string model = data_root() + "/models/CesiumMilkTruck.glb";
  std::vector<std::string> hdris;  // default: the hard-sun and the soft-sky HDRI below
  std::vector<std::string> methods{"stratified", "independent", "brdf_only"};
  std::string out = ".";
  int width = 160, height = 90, ref_spp = 1024, max_spp = 64, max_depth = 6;
  bool json = false, exact_fresnel = false;
};

std::vector<std::string> split_commas(const std::string& v) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= v.size()) {
    const size_t end = std::min(v.find(',', start), v.size());
    out.push_back(v.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

int to_int(const std::string& key, const std::string& v, int lo, int hi) {
  return static_cast<int>(cli::parse_integer("render: " + key, v, lo, hi));
}

Args parse(const std::vector<std::string>& a) {
  Args r;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i] == "--json" || a[i] == "--exact-fresnel") {
      (a[i] == "--json" ? r.json : r.exact_fresnel) = true;
      continue;
    }
    SL_CHECK(i + 1 < a.size(), "render: ", a[i], " needs a value (try render --help)");
    const std::string& k = a[i];
    const std::string& v = a[++i];
    if (k == "--model") r.model = v;
    else if (k == "--hdri") r.hdris.push_back(v);
    else if (k == "--methods") {
      r.methods = split_commas(v);
      for (const std::string& m : r.methods)
        SL_CHECK(m == "stratified" || m == "independent" || m == "brdf_only", "render: --methods entry '", m,
                 "' is not one of stratified, independent, brdf_only");
    }
    else if (k == "--out") r.out = v;
    else if (k == "--width") r.width = to_int(k, v, 8, 4096);
    else if (k == "--height") r.height = to_int(k, v, 8, 4096);
    else if (k == "--ref-spp") r.ref_spp = to_int(k, v, 1, 1 << 16);
    else if (k == "--max-spp") r.max_spp = to_int(k, v, 1, 1 << 14);
    else if (k == "--max-depth") r.max_depth = to_int(k, v, 1, 64);
    else fail("render: unknown argument '", k, "' (try render --help)");
  }
  if (r.hdris.empty())
    r.hdris = {data_root() + "/hdri/chinese_garden_1k.hdr", data_root() + "/hdri/potsdamer_platz_1k.hdr"};
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
  std::string hdri, method;
  int spp;
  double time_ms, rmse, noise, relative_noise, mean;
};

double mean_value(const Tensor& a) {
  const float* p = a.data<float>();
  double s = 0.0;
  for (int64_t i = 0; i < a.numel(); ++i) s += p[i];
  return s / double(a.numel());
}

PathTracerOptions method_options(const std::string& method, const Args& args) {
  PathTracerOptions o;
  o.max_depth = args.max_depth;
  o.exact_fresnel = args.exact_fresnel;
  o.estimator = method == "stratified" ? PathEstimator::Stratified : PathEstimator::Independent;
  o.environment_sampling = method != "brdf_only";
  return o;
}

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
          "usage: streetlight-bench render [--model FILE.glb] [--hdri FILE.hdr ...] [--out DIR] [--width W]\n"
          "         [--height H] [--ref-spp N] [--max-spp N] [--max-depth D] [--methods LIST] [--exact-fresnel]\n"
          "         [--json]\n"
          "  Path-traces the model on a ground plane under each HDRI at 1, 2, 4, ... --max-spp samples per\n"
          "  pixel with each estimator of LIST (comma-separated; default stratified,independent,brdf_only:\n"
          "  stratified = NEE + MIS with Owen-scrambled Sobol samples, the default; independent = NEE + MIS\n"
          "  with independent numbers, the original independent estimator; brdf_only = BRDF sampling alone) and\n"
          "  reports time, RMSE against a --ref-spp stratified reference, and the pixel noise from two seeds.\n"
          "  Writes DIR/render_bench.csv, DIR/render_bench.png (log-log RMSE vs time in ms) and\n"
          "  DIR/render_reference_<hdri>.exr. Defaults: CesiumMilkTruck.glb, chinese_garden_1k.hdr (hard sun)\n"
          "  and potsdamer_platz_1k.hdr (soft sky) from $STREETLIGHT_DATA (else ../shared/data), 160x90,\n"
          "  reference 1024 spp, sweep to 64 spp, depth 6. --hdri may repeat.\n");
      return 0;
    }
  const Args args = parse(argv);
  SL_CHECK(args.ref_spp >= args.max_spp, "render: --ref-spp (", args.ref_spp, ") must be >= --max-spp (",
           args.max_spp, ")");
  Bounds3 model_bounds;
  const Mesh scene = build_scene(args.model, model_bounds);
  const Camera camera = three_quarter_view(model_bounds, args.width, args.height);
  std::vector<Point> pts;
  std::filesystem::create_directories(args.out);
  for (const std::string& hdri : args.hdris) {
    const std::string name = std::filesystem::path(hdri).stem().string();
    ImageReadOptions ro;
    ro.channels = 3;
    const EnvironmentMap env(read_image(hdri, ro));
    const PathTracer tracer(scene, env);
    std::fprintf(stderr, "render: %s: %zu triangles, HDRI %dx%d, %dx%d pixels, %d threads\n", name.c_str(),
                 scene.triangle_count(), env.width(), env.height(), args.width, args.height, omp_get_max_threads());
    PathTracerOptions o = method_options("stratified", args);
    o.spp = args.ref_spp;
    o.seed = 1000003;
    std::fprintf(stderr, "render: reference at %d spp...\n", args.ref_spp);
    const double t_ref = now_ms();
    const PathTracerImage ref = tracer.render(camera, o);
    std::fprintf(stderr, "render: reference took %.1f s\n", (now_ms() - t_ref) / 1000.0);
    const double ref_mean = mean_value(ref.radiance);
    write_image(args.out + "/render_reference_" + name + ".exr", ref.radiance);

    for (const std::string& method : args.methods)
      for (int spp = 1; spp <= args.max_spp; spp *= 2) {
        o = method_options(method, args);
        o.spp = spp;
        o.seed = 1;
        const double t0 = now_ms();
        const PathTracerImage img = tracer.render(camera, o);
        const double time_ms = now_ms() - t0;
        o.seed = 2;
        const PathTracerImage other = tracer.render(camera, o);
        const double noise = rmse(img.radiance, other.radiance) / std::sqrt(2.0);
        const Point p{name, method, spp, time_ms, rmse(img.radiance, ref.radiance), noise,
                      ref_mean > 0 ? noise / ref_mean : 0.0, mean_value(img.radiance)};
        pts.push_back(p);
        if (args.json)
          std::printf(
              "{\"bench\":\"render\",\"hdri\":\"%s\",\"method\":\"%s\",\"spp\":%d,\"time_ms\":%.3f,"
              "\"rmse\":%.6g,\"noise\":%.6g,\"relative_noise\":%.6g,\"mean\":%.6g,\"reference_mean\":%.6g}\n",
              p.hdri.c_str(), p.method.c_str(), p.spp, p.time_ms, p.rmse, p.noise, p.relative_noise, p.mean,
              ref_mean);
        else
          std::printf("%-22s %-11s spp %5d  time %9.1f ms  rmse %.5g  noise %.5g (%.4f of mean)  mean %.5g/%.5g\n",
                      p.hdri.c_str(), p.method.c_str(), p.spp, p.time_ms, p.rmse, p.noise, p.relative_noise, p.mean,
                      ref_mean);
        std::fflush(stdout);
      }
  }

  const std::string csv = args.out + "/render_bench.csv";
  {
    std::ostringstream f;
    f << "hdri,method,spp,time_ms,rmse,noise,relative_noise,mean\n";
    for (const Point& p : pts)
      f << p.hdri << ',' << p.method << ',' << p.spp << ',' << p.time_ms << ',' << p.rmse << ',' << p.noise << ','
        << p.relative_noise << ',' << p.mean << '\n';
    write_file_atomic(csv, f.str());
  }
  ImageWriteOptions wo;
  wo.transfer = Transfer::Linear;  // the plot's colours are display values already
  std::vector<cli::PlotPoint> plot_points;
  for (const Point& p : pts) plot_points.push_back({p.hdri + ":" + p.method, p.time_ms, p.rmse});
  write_image(args.out + "/render_bench.png", cli::error_time_plot(plot_points), wo);
  std::fprintf(stderr, "render: wrote %s, render_bench.png, render_reference_*.exr\n", csv.c_str());
  return 0;
}

Registrar reg_render("render", "path tracer RMSE and two-seed noise vs time: stratified, independent, BRDF-only",
                     &run_render);

}  // namespace
}  // namespace sl::bench
