// streetlight-render: path-traces glTF models under an HDRI from a camera of the user's choice
//, with the reference path tracer (render/path_tracer.h) driven progressively to a
// sample, time or noise budget (render/progressive_render.h).
//
// Scene: every --scene file in its own glTF frame (world = glTF frame, +Y up, metres), plus
// with --ground a grey diffuse square (Disney roughness 1) at the lowest point of the models.
// Lighting: the HDRI at infinity, azimuth rotated by --rotate-deg (a feature at panorama
// azimuth φ moves to φ + D; render/equirect.h: φ = 0 looks down −Z, +90° towards +X).
// Camera: pinhole at --cam looking at --look, image up = world +Y, --fov = horizontal field
// of view. Output: .exr = linear HDR radiance in the HDRI's units; .png =
// clip((exposure·L)^(1/2.2), 0, 1) with --exposure (default: the median pixel maps to 0.4).
// Written through a temporary file and renamed: bad input or a failure leaves no file.
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "render/camera.h"
#include "render/environment_map.h"
#include "render/exposure.h"
#include "render/gltf_loader.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "render/progressive_render.h"
#include "tools/common/cli.h"
#include "util/error.h"
#include "util/math.h"

using sl::data::ImageReadOptions;
using sl::data::ImageWriteOptions;
using sl::data::read_image;
using sl::data::Transfer;
using sl::data::write_image;
using sl::render::Bounds3;
using sl::render::Camera;
using sl::render::EnvironmentMap;
using sl::render::exposure_for_ldr_median;
using sl::render::intrinsics_from_fov;
using sl::render::load_gltf;
using sl::render::make_ground_plane;
using sl::render::Material;
using sl::render::Mesh;
using sl::render::PathEstimator;
using sl::render::PathTracer;
using sl::render::PathTracerOptions;
using sl::render::ProgressiveOptions;
using sl::render::ProgressiveResult;
using sl::render::ProgressiveStatus;
using sl::render::render_progressive;
using sl::render::RenderPass;
using sl::render::rotation_from_yaw_pitch_roll;

namespace fs = std::filesystem;
using namespace sl;

namespace {

glm::dvec3 parse_vec3(const std::string& flag, const std::string& v) {
  std::vector<double> out;
  std::string item;
  std::istringstream is(v);
  while (std::getline(is, item, ',')) {
    size_t used = 0;
    double d = NAN;
    try {
      d = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    SL_CHECK(used == item.size() && !item.empty() && std::isfinite(d), flag, " expects three numbers 'X,Y,Z', got '",
             v, "'");
    out.push_back(d);
  }
  SL_CHECK(out.size() == 3 && (v.empty() || v.back() != ','), flag, " expects three numbers 'X,Y,Z', got '", v,
           "'");
  return {out[0], out[1], out[2]};
}

// The output path's format: .exr or .png; its folder must exist (checked before rendering).
std::string output_format(const std::string& out) {
  const fs::path p(out);
  std::string ext = p.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  SL_CHECK(ext == ".exr" || ext == ".png", "--out '", out, "' must end in .exr or .png");
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  SL_CHECK(fs::is_directory(dir, ec), "--out '", out, "': folder '", dir.string(), "' does not exist");
  SL_CHECK(!fs::is_directory(p, ec), "--out '", out, "' is a folder");
  return ext;
}

Mesh load_scenes(const std::vector<std::string>& files, double ground_albedo, bool ground) {
  SL_CHECK(!files.empty(), "--scene is required (a .glb or .gltf file)");
  Mesh scene;
  for (const std::string& f : files) {
    SL_CHECK(fs::is_regular_file(f), "--scene '", f, "' does not exist");
    scene.append(load_gltf(f));
  }
  SL_CHECK(scene.triangle_count() > 0, "--scene: the models have no triangles");
  if (ground) {
    const Bounds3 b = scene.bounds();
    Material m;
    m.name = "ground";
    m.base_color_factor = glm::vec4(float(ground_albedo), float(ground_albedo), float(ground_albedo), 1.0f);
    m.metallic = 0.0f;
    m.roughness = 1.0f;
    const float size = std::max(200.0f, 20.0f * glm::length(b.extent()));
    scene.append(make_ground_plane(size, b.lo.y, m, b.centre().x, b.centre().z));
  }
  return scene;
}

Tensor to_ldr(const Tensor& radiance, double exposure) {
  Tensor out = radiance.contiguous().clone();
  float* p = out.data<float>();
  for (int64_t i = 0; i < out.numel(); ++i)
    p[i] = float(ldr_encode(p[i], exposure));
  return out;
}

int run(int argc, char** argv) {
  cli::Args args(
      "streetlight-render",
      "--scene A.glb [--scene B.glb ...] --hdri SKY.hdr --cam X,Y,Z --look X,Y,Z --fov DEG --width W --height H\n"
      "       --spp N [--seed S] [--ground ALBEDO] [--rotate-deg D] [--seconds T] [--target-noise E] --out IMG.exr|png\n\n"
      "Path-traces glTF models under an HDRI (reference path tracer: environment importance sampling,\n"
      "BRDF sampling, MIS, stratified Sobol samples). World = the glTF frame (+Y up, metres); the HDRI\n"
      "follows render/equirect.h (panorama centre looks down -Z, +X at azimuth +90 deg). Renders in\n"
      "doubling passes until --spp samples per pixel, --seconds of wall time or --target-noise (the\n"
      "estimated standard deviation of a displayed 0-1 pixel value, from two independent seeds) is reached.",
      {{"--scene", "FILE", "glTF model (.glb/.gltf), in its own frame", true},
       {"--hdri", "FILE", "equirectangular HDR sky (.hdr/.exr)"},
       {"--cam", "X,Y,Z", "camera position (m)"},
       {"--look", "X,Y,Z", "point the camera looks at (m); image up is world +Y"},
       {"--fov", "DEG", "horizontal field of view in degrees (default 50)"},
       {"--width", "W", "image width in pixels (default 640)"},
       {"--height", "H", "image height in pixels (default 360)"},
       {"--spp", "N", "samples per pixel (default 64; the cap when --seconds/--target-noise is given: 65536)"},
       {"--seed", "S", "random seed (default 0)"},
       {"--ground", "ALBEDO", "add a grey diffuse ground plane of this albedo in [0, 1] under the models"},
       {"--rotate-deg", "D", "rotate the HDRI in azimuth by D degrees (default 0)"},
       {"--seconds", "T", "stop after about T seconds of rendering"},
       {"--target-noise", "E", "stop when the estimated LDR noise is <= E (e.g. 0.004 = one 8-bit level)"},
       {"--max-depth", "D", "surface interactions per path (default 8)"},
       {"--exposure", "E", "PNG and noise exposure (default: the median pixel maps to 0.4 after 1/2.2)"},
       {"--fresnel", "exact|schlick", "dielectric Fresnel (default exact, as Cycles)"},
       {"--estimator", "stratified|independent", "sample pattern (independent = the original independent estimator)"},
       {"--json", "", "print the result as one JSON line on stdout"},
       {"--out", "FILE", "output image: .exr (linear HDR) or .png (LDR)"}});
  if (!args.parse(argc, argv)) return 0;

  // Validate every argument before any expensive work.
  SL_CHECK(args.has("--hdri"), "--hdri is required (an .hdr or .exr panorama)");
  SL_CHECK(args.has("--cam"), "--cam X,Y,Z is required");
  SL_CHECK(args.has("--look"), "--look X,Y,Z is required");
  SL_CHECK(args.has("--out"), "--out FILE.exr|png is required");
  const std::string out = args.get("--out");
  const std::string ext = output_format(out);
  const glm::dvec3 cam = parse_vec3("--cam", args.get("--cam"));
  const glm::dvec3 look = parse_vec3("--look", args.get("--look"));
  SL_CHECK(glm::length(look - cam) > 1e-9, "--look ", args.get("--look"), " equals --cam: no viewing direction");
  const double fov = args.number("--fov", 50.0);
  SL_CHECK(fov > 0.0 && fov < 180.0, "--fov must be in (0, 180) degrees, got ", fov);
  const int64_t width = args.integer("--width", 640), height = args.integer("--height", 360);
  SL_CHECK(width >= 1 && width <= 16384, "--width must be in [1, 16384], got ", width);
  SL_CHECK(height >= 1 && height <= 16384, "--height must be in [1, 16384], got ", height);
  const bool budgeted = args.has("--seconds") || args.has("--target-noise");
  const int64_t spp = args.integer("--spp", budgeted ? 65536 : 64);
  SL_CHECK(spp >= 1 && spp <= (1 << 20), "--spp must be in [1, 1048576], got ", spp);
  const int64_t seed = args.integer("--seed", 0);
  SL_CHECK(seed >= 0, "--seed must be >= 0, got ", seed);
  const double seconds = args.number("--seconds", 0.0);
  SL_CHECK(!args.has("--seconds") || (seconds > 0.0 && std::isfinite(seconds)), "--seconds must be > 0, got ",
           args.get("--seconds"));
  const double target = args.number("--target-noise", 0.0);
  SL_CHECK(!args.has("--target-noise") || (target > 0.0 && target < 1.0), "--target-noise must be in (0, 1), got ",
           args.get("--target-noise"));
  SL_CHECK(!args.has("--target-noise") || spp >= 2, "--target-noise needs --spp >= 2 (two seeds), got ", spp);
  const double ground = args.number("--ground", 0.0);
  SL_CHECK(!args.has("--ground") || (ground >= 0.0 && ground <= 1.0), "--ground albedo must be in [0, 1], got ",
           args.get("--ground"));
  const double rotate = args.number("--rotate-deg", 0.0);
  SL_CHECK(std::isfinite(rotate), "--rotate-deg must be a finite number, got ", args.get("--rotate-deg"));
  const int64_t depth = args.integer("--max-depth", 8);
  SL_CHECK(depth >= 1 && depth <= 1024, "--max-depth must be in [1, 1024], got ", depth);
  const double exposure = args.number("--exposure", 0.0);
  SL_CHECK(!args.has("--exposure") || (exposure > 0.0 && std::isfinite(exposure)), "--exposure must be > 0, got ",
           args.get("--exposure"));
  const std::string fresnel = args.get("--fresnel", "exact"), estimator = args.get("--estimator", "stratified");
  SL_CHECK(fresnel == "exact" || fresnel == "schlick", "--fresnel must be exact or schlick, got '", fresnel, "'");
  SL_CHECK(estimator == "stratified" || estimator == "independent",
           "--estimator must be stratified or independent, got '", estimator, "'");

  const std::string hdri = args.get("--hdri");
  SL_CHECK(fs::is_regular_file(hdri), "--hdri '", hdri, "' does not exist");
  ImageReadOptions ro;
  ro.channels = 3;
  EnvironmentMap env(read_image(hdri, ro));
  if (rotate != 0.0) env = env.rotated(rotate * kPi / 180.0);
  const Mesh scene = load_scenes(args.all("--scene"), ground, args.has("--ground"));

  const glm::dvec3 f = glm::normalize(look - cam);
  const Camera camera(intrinsics_from_fov(fov * kPi / 180.0, int(width), int(height)),
                      rotation_from_yaw_pitch_roll(std::atan2(f.x, -f.z), std::asin(std::clamp(f.y, -1.0, 1.0)), 0.0),
                      cam);
  const PathTracer tracer(scene, env);
  PathTracerOptions po;
  po.max_depth = int(depth);
  po.exact_fresnel = fresnel == "exact";
  po.estimator = estimator == "stratified" ? PathEstimator::Stratified : PathEstimator::Independent;
  std::fprintf(stderr, "render: %zu triangles, HDRI %dx%d, %lldx%lld pixels, %d threads\n", scene.triangle_count(),
               env.width(), env.height(), (long long)width, (long long)height, omp_get_max_threads());

  ProgressiveOptions prog;
  prog.seed = uint64_t(seed);
  prog.max_spp = int(spp);
  prog.seconds = seconds;
  prog.target_noise = target;
  prog.two_seeds = args.has("--target-noise");
  prog.exposure = exposure;
  // The bar counts samples, or tenths of a second under a time budget (its ETA is then the budget's).
  const bool by_time = seconds > 0.0;
  cli::Progress bar("render", by_time ? int64_t(std::ceil(seconds * 10)) : spp);
  const RenderPass pass = [&](uint64_t s, int64_t offset, int n) {
    PathTracerOptions o = po;
    o.seed = s;
    o.sample_offset = offset;
    o.spp = n;
    return tracer.render(camera, o).radiance;
  };
  const ProgressiveResult r = render_progressive(pass, prog, [&](const ProgressiveStatus& st) {
    char extra[64] = "";
    std::snprintf(extra, sizeof extra, "%d spp", st.spp);
    if (st.noise >= 0) std::snprintf(extra, sizeof extra, "%d spp, noise %.5f", st.spp, st.noise);
    bar.update(by_time ? std::min<int64_t>(int64_t(st.seconds * 10), int64_t(std::ceil(seconds * 10))) : st.spp,
               extra);
  });
  char summary[128];
  std::snprintf(summary, sizeof summary, "(%d spp%s)", r.status.spp, r.status.noise >= 0 ? ", noise estimated" : "");
  bar.finish(summary);

  const double used_exposure = exposure > 0.0 ? exposure : exposure_for_ldr_median(r.radiance, 0.4);
  if (ext == ".exr") {
    write_image(out, r.radiance);
  } else {
    ImageWriteOptions wo;
    wo.transfer = Transfer::Linear;  // the LDR curve is applied above
    write_image(out, to_ldr(r.radiance, used_exposure), wo);
  }
  std::fprintf(stderr, "render: wrote %s (%d spp, %.1f s, exposure %.4g)\n", out.c_str(), r.status.spp,
               r.status.seconds, used_exposure);
  if (args.has("--json"))
    std::printf("%s\n", nlohmann::json{{"out", out},
                                        {"spp", r.status.spp},
                                        {"seconds", r.status.seconds},
                                        {"noise", r.status.noise},
                                        {"exposure", used_exposure}}
                            .dump()
                            .c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::run_main([&] { return run(argc, argv); });
}
