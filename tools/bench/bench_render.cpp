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

double rmse(const Tensor& a, const Tensor& b) {
  const float *pa = a.data<float>(), *pb = b.data<float>();
  double s = 0.0;
  for (int64_t i = 0; i < a.numel(); ++i) s += double(pa[i] - pb[i]) * double(pa[i] - pb[i]);
  return std::sqrt(s / double(a.numel()));
}

// ---- a minimal log-log line plot drawn into an RGB buffer

struct Canvas {
  int w, h;
  std::vector<glm::vec3> px;
  Canvas(int width, int height) : w(width), h(height), px(size_t(width) * height, glm::vec3(1.0f)) {}
  void dot(int x, int y, const glm::vec3& c, int radius = 1) {
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx)
        if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h) px[size_t(y + dy) * w + x + dx] = c;
  }
  void line(double x0, double y0, double x1, double y1, const glm::vec3& c, int radius = 1) {
    const int n = std::max(1, int(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))));
    for (int i = 0; i <= n; ++i) {
      const double t = double(i) / n;
      dot(int(std::lround(x0 + t * (x1 - x0))), int(std::lround(y0 + t * (y1 - y0))), c, radius);
    }
  }
  // 3×5 bitmap digits, '.', '-' and 'e' (enough for tick labels such as 1e-2), scaled ×2.
  void text(int x, int y, const std::string& s, const glm::vec3& c) {
    static const std::map<char, const char*> glyphs = {
        {'0', "111101101101111"}, {'1', "010110010010111"}, {'2', "111001111100111"}, {'3', "111001111001111"},
        {'4', "101101111001001"}, {'5', "111100111001111"}, {'6', "111100111101111"}, {'7', "111001001001001"},
        {'8', "111101111101111"}, {'9', "111101111001111"}, {'.', "000000000000010"}, {'-', "000000111000000"},
        {'e', "000111101110111"}};
    for (char ch : s) {
      auto it = glyphs.find(ch);
      if (it != glyphs.end())
        for (int r = 0; r < 5; ++r)
          for (int k = 0; k < 3; ++k)
            if (it->second[r * 3 + k] == '1')
              for (int sy = 0; sy < 2; ++sy)
                for (int sx = 0; sx < 2; ++sx) dot(x + 2 * k + sx, y + 2 * r + sy, c, 0);
      x += 8;
    }
  }
  Tensor tensor() const {
    Tensor t = Tensor::empty({3, h, w});
    float* p = t.data<float>();
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < px.size(); ++i) p[c * px.size() + i] = px[i][c];
    return t;
  }
};

struct Point {
  std::string method;
  int spp;
  double time_ms, rmse;
};

Tensor plot(const std::vector<Point>& pts) {
  Canvas cv(640, 420);
  const int left = 70, right = 620, top = 20, bottom = 370;
  double tx0 = 1e300, tx1 = -1e300, ey0 = 1e300, ey1 = -1e300;
  for (const Point& p : pts) {
    tx0 = std::min(tx0, std::log10(p.time_ms));
    tx1 = std::max(tx1, std::log10(p.time_ms));
    ey0 = std::min(ey0, std::log10(std::max(p.rmse, 1e-12)));
    ey1 = std::max(ey1, std::log10(std::max(p.rmse, 1e-12)));
  }
  tx0 = std::floor(tx0), tx1 = std::ceil(tx1 + 1e-9), ey0 = std::floor(ey0), ey1 = std::ceil(ey1 + 1e-9);
  auto X = [&](double t) { return left + (std::log10(t) - tx0) / (tx1 - tx0) * (right - left); };
  auto Y = [&](double e) { return bottom - (std::log10(std::max(e, 1e-12)) - ey0) / (ey1 - ey0) * (bottom - top); };
  const glm::vec3 grey(0.8f), black(0.0f);
  for (int k = int(tx0); k <= int(tx1); ++k) {  // decade grid and labels (time in ms)
    const double x = X(std::pow(10.0, k));
    cv.line(x, top, x, bottom, grey, 0);
    cv.text(int(x) - 12, bottom + 10, "1e" + std::to_string(k), black);
  }
  for (int k = int(ey0); k <= int(ey1); ++k) {
    const double y = Y(std::pow(10.0, k));
    cv.line(left, y, right, y, grey, 0);
    cv.text(8, int(y) - 5, "1e" + std::to_string(k), black);
  }
  cv.line(left, bottom, right, bottom, black);
  cv.line(left, top, left, bottom, black);
  const std::map<std::string, glm::vec3> colour = {{"env_mis", {0.1f, 0.3f, 0.9f}}, {"brdf_only", {0.9f, 0.15f, 0.1f}}};
  for (const auto& [method, c] : colour) {
    const Point* prev = nullptr;
    for (const Point& p : pts) {
      if (p.method != method) continue;
      if (prev) cv.line(X(prev->time_ms), Y(prev->rmse), X(p.time_ms), Y(p.rmse), c);
      cv.dot(int(X(p.time_ms)), int(Y(p.rmse)), c, 3);
      prev = &p;
    }
  }
  return cv.tensor();
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
  write_image(args.out + "/render_bench.png", plot(pts), wo);
  write_image(args.out + "/render_reference.exr", ref.radiance);
  std::fprintf(stderr, "render: wrote %s, render_bench.png, render_reference.exr\n", csv.c_str());
  return 0;
}

Registrar reg_render("render", "path tracer RMSE vs time, with and without environment importance sampling",
                     &run_render);

}  // namespace
}  // namespace sl::bench
