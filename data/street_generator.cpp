// Rendering and writing one generated street sample (see street_generator.h).
#include "data/street_generator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "data/hdri_folder.h"
#include "data/hdri_split.h"
#include "data/image_io.h"
#include "data/object_placement.h"
#include "data/panorama.h"
#include "data/panorama_sample.h"
#include "data/procedural_car.h"
#include "data/sky_model.h"
#include "data/sun_extraction.h"
#include "render/camera.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/gltf_writer.h"
#include "render/path_tracer.h"
#include "render/progressive_render.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"
#include "util/file.h"

using sl::render::Bounds3;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::EnvironmentMap;
using sl::render::exposure_for_ldr_median;
using sl::render::Intrinsics;
using sl::render::intrinsics_from_fov;
using sl::render::Mesh;
using sl::render::PathTracer;
using sl::render::PathTracerImage;
using sl::render::PathTracerOptions;
using sl::render::placed_mesh;
using sl::render::Placement;
using sl::render::ProgressiveOptions;
using sl::render::ProgressiveResult;
using sl::render::ProgressiveStatus;
using sl::render::Projection;
using sl::render::render_progressive;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::write_glb;

namespace sl::data {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// Independent random streams per (sample, purpose): adding a view or a config knob never
// shifts the random choices of another part of the sample.
enum Purpose : uint64_t { kLight = 1, kViews = 2, kObject = 3, kScene = 4, kPanoSeed = 100, kViewSeed = 200,
                        kProbeSeed = 300 };

Rng purpose_rng(const StreetGeneratorConfig& c, int64_t index, Purpose p) {
  return Rng(hash_counter(c.seed, static_cast<uint64_t>(index), p), p);
}

json vec3_json(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

struct Lighting {
  Tensor env;      // [3, W/2, W] the map the scene is lit with
  Tensor sky_hdr;  // [3, sky_height, sky_width]
  glm::dvec3 sun_direction{0.0, 1.0, 0.0};
  json meta;
};

// Texels that are negative, NaN or Inf become 0 (EnvironmentMap rejects them; real HDRIs have some).
void sanitize(Tensor& t) {
  float* p = t.data<float>();
  for (int64_t i = 0; i < t.numel(); ++i)
    if (!(p[i] >= 0.0f) || !std::isfinite(p[i])) p[i] = 0.0f;
}

Lighting make_lighting(const StreetGeneratorConfig& c, int64_t index) {
  Rng rng = purpose_rng(c, index, kLight);
  Lighting out;
  const int env_w = c.environment_width, env_h = env_w / 2;
  // The fraction is drawn only when HDRIs are configured, so sky-model datasets stay bit-identical.
  if (!c.hdri_folder.empty() && (c.hdri_fraction >= 1.0 || rng.uniform() < c.hdri_fraction)) {
    const HdriFolder folder = c.hdri_split.empty()
                                  ? HdriFolder(c.hdri_folder)
                                  : HdriFolder(read_hdri_split(c.hdri_split).split_paths(c.hdri_folder, c.hdri_split_name));
    const size_t file = static_cast<size_t>(rng.randint(static_cast<int64_t>(folder.size())));
    Tensor pano = folder.load(file).contiguous();
    sanitize(pano);
    // A whole-column roll is exact; the sun is re-extracted from the rotated map itself.
    const int64_t W = pano.size(2);
    const int64_t shift = rng.randint(W);
    const double rotation = 2.0 * kPi * static_cast<double>(shift) / static_cast<double>(W);
    pano = rotate_azimuth(pano, rotation).contiguous();
    const SunHardness hardness = sun_hardness(pano);
    const SunEstimate& sun = hardness.sun;
    out.sun_direction = sun.direction;
    out.env = resize_area(pano, env_h, env_w).contiguous();
    out.sky_hdr = resize_area(pano, c.sky_height, c.sky_width).contiguous();
    out.meta = {{"source", "hdri"},
                {"hdri_file", fs::path(folder.path(file)).filename().string()},
                {"hdri_rotation_deg", rotation / kDegToRad},
                {"sun_found", sun.found},
                {"sun_hard", hardness.hard},  // data/panorama_sample.h: only a hard sun is a direction label
                {"sun_share", hardness.share}};
  } else {
    SkyParams p;
    p.sun_elevation_rad = rng.uniform(c.elevation_min_deg, c.elevation_max_deg) * kDegToRad;
    p.sun_azimuth_rad = rng.uniform(-kPi, kPi);
    p.turbidity = rng.uniform(c.turbidity_min, c.turbidity_max);
    p.ground_albedo = c.ground_albedo;
    const bool clouds = rng.uniform() < c.cloud_probability;
    p.cloud_cover = clouds ? rng.uniform(c.cloud_cover_min, c.cloud_cover_max) : 0.0;
    p.cloud_seed = rng.next_u64() >> 12;  // fits a JSON double exactly
    const PreethamSky sky(p);
    out.sun_direction = sky.sun_direction();
    out.env = sky.render(env_h, env_w).contiguous();
    // Energy-preserving downsampling of the higher-resolution render (never point-samples the sun).
    out.sky_hdr = resize_area(out.env, c.sky_height, c.sky_width).contiguous();
    out.meta = {{"source", "preetham"},
                {"sun_elevation_deg", p.sun_elevation_rad / kDegToRad},
                {"sun_azimuth_deg", p.sun_azimuth_rad / kDegToRad},
                {"turbidity", p.turbidity},
                {"ground_albedo", p.ground_albedo},
                {"cloud_cover", p.cloud_cover},
                {"cloud_seed", p.cloud_seed},
                {"sun_radiance_rgb", vec3_json(sky.sun_radiance())},
                {"zenith_luminance", sky.zenith_luminance()}};
  }
  return out;
}

struct PanoramaRender {
  Tensor radiance;  // [3, H, W]
  Tensor sky_mask;  // [1, H, W], 1 where the pixel-centre ray escapes the scene
};

// The path tracer's estimator over equirectangular pixels, with render()'s counter layout:
// sample s of pixel p is path sample s of stream p (PathTracer::pixel_jitter, then radiance()).
PanoramaRender render_panorama(const PathTracer& tracer, const glm::dvec3& origin, int H, int W,
                               const PathTracerOptions& o) {
  PathTracer::validate(o);
  PanoramaRender out{Tensor::zeros({3, H, W}), Tensor::zeros({1, H, W})};
  float* rad = out.radiance.data<float>();
  float* sky = out.sky_mask.data<float>();
  const size_t plane = static_cast<size_t>(H) * W;
  const glm::vec3 org(origin);
#pragma omp parallel for schedule(dynamic, 1)
  for (int row = 0; row < H; ++row) {
    for (int col = 0; col < W; ++col) {
      const uint64_t pixel = static_cast<uint64_t>(row) * W + col;
      glm::dvec3 sum(0.0);
      int kept = 0;
      for (int k = 0; k < o.spp; ++k) {
        const uint64_t s = static_cast<uint64_t>(o.sample_offset) + k;
        const glm::vec2 jitter = PathTracer::pixel_jitter(pixel, s, o);
        const render::equirect::Dir d =
            render::equirect::uv_to_direction(col + double(jitter.x), row + double(jitter.y), W, H);
        const glm::vec3 L = tracer.radiance(org, glm::vec3(d.x, d.y, d.z), pixel, s, o);
        if (std::isfinite(L.x + L.y + L.z)) sum += glm::dvec3(L), ++kept;
      }
      sum /= o.spp;  // a dropped sample counts as black, as in PathTracer::render
      for (int ch = 0; ch < 3; ++ch) rad[ch * plane + pixel] = static_cast<float>(std::min(sum[ch], 3.0e38));
      const render::equirect::Dir d = render::equirect::uv_to_direction(col + 0.5, row + 0.5, W, H);
      sky[pixel] = tracer.first_hit(org, glm::vec3(d.x, d.y, d.z)).hit ? 0.0f : 1.0f;
    }
  }
  return out;
}

std::vector<Camera> make_views(const StreetGeneratorConfig& c, int64_t index) {
  Rng rng = purpose_rng(c, index, kViews);
  const Intrinsics k = intrinsics_from_fov(c.view_fov_deg * kDegToRad, c.view_width, c.view_height);
  std::vector<Camera> views;
  for (int v = 0; v < c.view_count; ++v) {
    // View 0 looks down the street (it receives the inserted object); the others move forward
    // and sideways and turn, like the other cameras or frames of a driving rig.
    const double yaw_range = v == 0 ? 0.25 * c.view_yaw_range_deg : c.view_yaw_range_deg;
    const double yaw = rng.uniform(-yaw_range, yaw_range) * kDegToRad;
    const double pitch = rng.uniform(-c.view_pitch_range_deg, c.view_pitch_range_deg) * kDegToRad;
    glm::dvec3 pos(0.0, c.camera_height_m, 0.0);
    if (v > 0) {
      pos.x = rng.uniform(-c.view_lateral_range_m, c.view_lateral_range_m);
      pos.z = -rng.uniform(0.0, c.view_forward_range_m);
    }
    views.emplace_back(k, rotation_from_yaw_pitch_roll(yaw, pitch, 0.0), pos);
  }
  return views;
}

Tensor sky_mask_from_hits(const Tensor& mask) {
  Tensor out = Tensor::zeros({1, mask.size(1), mask.size(2)});
  const float* m = mask.data<float>();
  float* o = out.data<float>();
  for (int64_t i = 0; i < out.numel(); ++i) o[i] = m[i] > 0.5f ? 0.0f : 1.0f;
  return out;
}

struct Insertion {
  bool found = false;
  Mesh object;  // object frame
  Placement placement;
  Tensor coverage;  // [1, H, W]
  std::array<double, 4> box2d{};
  std::array<double, 7> box3d{};
};

// Fraction of n×n sub-pixel rays per pixel whose first hit is the object rather than the
// scene, inside the object's projected box (elsewhere it is 0). Returns the pixel count ≥ 0.5.
int coverage_mask(const PathTracer& scene, const PathTracer& object, const Camera& cam, const Mesh& placed,
                  int n, Tensor& coverage) {
  const Intrinsics& k = cam.intrinsics();
  coverage = Tensor::zeros({1, k.height, k.width});
  const Bounds3 b = placed.bounds();
  double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 p((i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z);
    const Projection pr = cam.project(p);
    if (!pr.in_front || pr.depth < 0.05) return 0;  // not entirely in front of the camera
    u0 = std::min(u0, pr.pixel.x), u1 = std::max(u1, pr.pixel.x);
    v0 = std::min(v0, pr.pixel.y), v1 = std::max(v1, pr.pixel.y);
  }
  const int c0 = std::max(0, static_cast<int>(std::floor(u0))), c1 = std::min(k.width - 1, static_cast<int>(u1));
  const int r0 = std::max(0, static_cast<int>(std::floor(v0))), r1 = std::min(k.height - 1, static_cast<int>(v1));
  if (c0 > c1 || r0 > r1) return 0;
  float* cov = coverage.data<float>();
  int visible = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : visible)
  for (int row = r0; row <= r1; ++row)
    for (int col = c0; col <= c1; ++col) {
      int hits = 0;
      for (int a = 0; a < n; ++a)
        for (int bb = 0; bb < n; ++bb) {
          const CameraRay r = cam.ray(col + (a + 0.5) / n, row + (bb + 0.5) / n);
          const glm::vec3 o(r.origin), d(r.direction);
          const PathTracer::PrimaryHit ho = object.first_hit(o, d);
          if (!ho.hit) continue;
          const PathTracer::PrimaryHit hs = scene.first_hit(o, d);
          if (!hs.hit || ho.distance <= hs.distance) ++hits;
        }
      const float f = static_cast<float>(hits) / static_cast<float>(n * n);
      cov[static_cast<size_t>(row) * k.width + col] = f;
      if (f >= 0.5f) ++visible;
    }
  return visible;
}

Insertion find_insertion(const StreetGeneratorConfig& c, int64_t index, const StreetScene& scene,
                         const PathTracer& scene_tracer, const EnvironmentMap& env, const std::vector<Camera>& views) {
  Rng rng = purpose_rng(c, index, kObject);
  Insertion ins;
  double base_scale = 1.0;
  if (c.object_mesh) {
    ins.object = *c.object_mesh;
    base_scale = scale_to_length(ins.object, c.object_length_m);
  } else {
    ProceduralCarParams p;
    p.length_m = c.object_length_m * rng.uniform(0.93, 1.07);
    p.width_m = 0.4 * p.length_m * rng.uniform(0.95, 1.05);
    p.height_m = 0.33 * p.length_m * rng.uniform(0.9, 1.1);
    p.paint_rgb = glm::vec3(rng.uniform(0.02, 0.8), rng.uniform(0.02, 0.8), rng.uniform(0.02, 0.8));
    ins.object = make_procedural_car(p);
  }
  const Camera& cam = views[0];
  const double r = scene.road_half_width_m;
  for (int attempt = 0; attempt < c.object_attempts; ++attempt) {
    Placement pl;
    pl.z_m = cam.position().z - rng.uniform(c.object_distance_min_m, c.object_distance_max_m);
    pl.x_m = rng.uniform(-r, r);
    pl.yaw_deg = rng.uniform() < 0.75 ? (rng.uniform() < 0.5 ? 90.0 : -90.0) + rng.uniform(-20.0, 20.0)
                                      : rng.uniform(-180.0, 180.0);
    pl.scale = base_scale * (c.object_mesh ? rng.uniform(0.95, 1.05) : 1.0);
    const FootprintXZ fp = placed_footprint(ins.object, pl);
    bool ok = fp.x0 > -r + 0.1 && fp.x1 < r - 0.1;  // on the road, clear of the curbs
    for (const FootprintXZ& o : scene.obstacles) ok = ok && !o.overlaps(fp, 0.3);
    for (const Camera& v : views) {
      const FootprintXZ cam_fp{v.position().x, v.position().z, v.position().x, v.position().z, "camera"};
      ok = ok && !cam_fp.overlaps(fp, 1.0);
    }
    if (!ok) continue;
    const Mesh placed = placed_mesh(ins.object, pl);
    const PathTracer object_tracer(placed, env);
    Tensor coverage;
    if (coverage_mask(scene_tracer, object_tracer, cam, placed, c.coverage_samples, coverage) <
        c.object_min_visible_pixels)
      continue;
    ins.found = true;
    ins.placement = pl;
    ins.coverage = coverage;
    const int W = cam.intrinsics().width, H = cam.intrinsics().height;
    const float* cov = coverage.data<float>();
    double x1 = W, y1 = H, x2 = 0, y2 = 0;
    for (int row = 0; row < H; ++row)
      for (int col = 0; col < W; ++col)
        if (cov[static_cast<size_t>(row) * W + col] > 0.0f)
          x1 = std::min<double>(x1, col), y1 = std::min<double>(y1, row), x2 = std::max<double>(x2, col + 1),
          y2 = std::max<double>(y2, row + 1);
    ins.box2d = {x1, y1, x2, y2};
    ins.box3d = kitti_box3d(ins.object, pl, cam);
    return ins;
  }
  return ins;
}

json camera_json(const Camera& cam) {
  const Intrinsics& k = cam.intrinsics();
  json rot = json::array();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rot.push_back(cam.rotation()[j][i]);  // row-major: glm is column-major
  return {{"intrinsics", {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"width", k.width}, {"height", k.height}}},
          {"rotation_cam_to_world", rot},
          {"position", vec3_json(cam.position())}};
}

void write_mask(const std::string& path, const Tensor& mask) {
  ImageWriteOptions o;
  o.transfer = Transfer::Linear;
  write_image(path, mask, o);
}

// LDR values are already gamma-encoded by to_ldr; they are stored as codes without a curve.
void write_ldr(const std::string& path, const Tensor& hdr, double exposure) { write_mask(path, to_ldr(hdr, exposure)); }

}  // namespace

std::string sample_id(int64_t index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06lld", static_cast<long long>(index));
  return buf;
}

GeneratedSample generate_street_sample(const StreetGeneratorConfig& c, int64_t index, const std::string& samples_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  GeneratedSample result;
  result.id = sample_id(index);
  // Written into a temporary sibling folder, renamed to <id>/ when complete (util/file.h); a
  // failure or a kill leaves no <id>/ behind.
  AtomicDirectory sample_dir((fs::path(samples_dir) / result.id).string());
  auto file = [&](const std::string& name) { return sample_dir.file(name); };
  {
    const Lighting light = make_lighting(c, index);
    const EnvironmentMap env(light.env);
    const StreetScene scene = build_street_scene(c.scene, hash_counter(c.seed, static_cast<uint64_t>(index), kScene));
    const PathTracer tracer(scene.mesh, env);
    PathTracerOptions opt;
    opt.spp = c.spp;
    opt.max_depth = c.max_depth;

    // Every image: exactly c.spp samples, or progressive passes to c.target_noise (capped by c.spp).
    ProgressiveOptions prog;
    prog.max_spp = c.spp;
    prog.target_noise = c.target_noise;
    prog.two_seeds = c.target_noise > 0.0;
    prog.auto_median_ldr = c.ldr_median;
    prog.single_pass_without_budget = true;
    json noise_meta = json::object();
    auto note = [&](const std::string& image, const ProgressiveStatus& st) {
      noise_meta[image] = {{"spp", st.spp}, {"noise", st.noise}};
    };

    const glm::dvec3 pano_pos(0.0, c.camera_height_m, 0.0);
    prog.seed = hash_counter(c.seed, static_cast<uint64_t>(index), kPanoSeed);
    PanoramaRender pano;
    const ProgressiveResult pano_r = render_progressive(
        [&](uint64_t seed, int64_t offset, int n) {
          PathTracerOptions o = opt;
          o.seed = seed, o.sample_offset = offset, o.spp = n;
          PanoramaRender pass = render_panorama(tracer, pano_pos, c.pano_height, c.pano_width, o);
          if (!pano.sky_mask.defined()) pano.sky_mask = pass.sky_mask;
          return pass.radiance;
        },
        prog);
    pano.radiance = pano_r.radiance;
    note("pano", pano_r.status);

    const std::vector<Camera> views = make_views(c, index);
    std::vector<PathTracerImage> renders;
    std::vector<uint64_t> view_seeds;
    std::vector<int> view_spp;
    // A view's progressive render; the depth, normal and mask come from any pass (pixel centres).
    auto render_view = [&](const PathTracer& t, const Camera& cam, const ProgressiveOptions& po) {
      PathTracerImage img;
      const ProgressiveResult r = render_progressive(
          [&](uint64_t seed, int64_t offset, int n) {
            PathTracerOptions o = opt;
            o.seed = seed, o.sample_offset = offset, o.spp = n;
            PathTracerImage pass = t.render(cam, o);
            if (!img.mask.defined()) img = pass;
            img.nonfinite_samples += pass.nonfinite_samples;
            return pass.radiance;
          },
          po);
      img.radiance = r.radiance;
      return std::pair{img, r.status};
    };
    for (size_t v = 0; v < views.size(); ++v) {
      prog.seed = hash_counter(c.seed, static_cast<uint64_t>(index), kViewSeed + v);
      view_seeds.push_back(prog.seed);
      auto [img, st] = render_view(tracer, views[v], prog);
      renders.push_back(img);
      view_spp.push_back(st.spp);
      note("view_" + std::to_string(v), st);
    }
    const double exposure = exposure_for_ldr_median(renders[0].radiance, c.ldr_median);
    result.exposure = exposure;

    write_image(file("pano_hdr.exr"), pano.radiance);
    write_ldr(file("pano_ldr.png"), pano.radiance, exposure);
    write_mask(file("pano_sky_mask.png"), pano.sky_mask);
    write_image(file("sky_hdr.exr"), light.sky_hdr);
    json view_meta = json::array();
    for (size_t v = 0; v < views.size(); ++v) {
      const std::string k = "view_" + std::to_string(v);
      write_image(file(k + "_hdr.exr"), renders[v].radiance);
      write_ldr(file(k + "_ldr.png"), renders[v].radiance, exposure);
      write_depth(file(k + "_depth.exr"), renders[v].depth);
      write_mask(file(k + "_sky_mask.png"), sky_mask_from_hits(renders[v].mask));
      json m = camera_json(views[v]);
      m["files"] = {{"hdr", k + "_hdr.exr"}, {"ldr", k + "_ldr.png"}, {"depth", k + "_depth.exr"},
                    {"sky_mask", k + "_sky_mask.png"}};
      view_meta.push_back(m);
    }

    json object_meta = nullptr;
    if (c.insertion) {
      const Insertion ins = find_insertion(c, index, scene, tracer, env, views);
      if (ins.found) {
        Mesh with = scene.mesh;
        const Mesh placed = placed_mesh(ins.object, ins.placement);
        with.append(placed);
        const PathTracer with_tracer(with, env);
        // The same per-pixel streams and samples as view 0 (see header).
        ProgressiveOptions same = prog;
        same.seed = view_seeds[0];
        same.max_spp = view_spp[0];
        same.target_noise = 0.0;
        same.single_pass_without_budget = !prog.two_seeds;  // view 0's pass sizes: bitwise the same streams
        Tensor without_radiance = renders[0].radiance;
        if (c.insertion_spp > 0) {
          // A cleaner pair: both images again at insertion.spp, one pass each, the same streams.
          same.max_spp = c.insertion_spp;
          same.single_pass_without_budget = true;
          auto [clean, clean_st] = render_view(tracer, views[0], same);
          note("insert_without_object", clean_st);
          without_radiance = clean.radiance;
        }
        auto [img, st] = render_view(with_tracer, views[0], same);
        note("insert_with_object", st);
        write_image(file("insert_with_object_hdr.exr"), img.radiance);
        write_ldr(file("insert_with_object_ldr.png"), img.radiance, exposure);
        write_image(file("insert_without_object_hdr.exr"), without_radiance);
        write_mask(file("insert_object_mask.png"), ins.coverage);
        write_glb(ins.object, file("object.glb"));
        const Placement& p = ins.placement;
        object_meta = {{"view", 0},
                       {"file", "object.glb"},
                       {"source", c.object_file.empty() ? "procedural_car" : c.object_file},
                       {"placement", {{"x_m", p.x_m}, {"z_m", p.z_m}, {"yaw_deg", p.yaw_deg}, {"scale", p.scale}}},
                       {"box2d", ins.box2d},
                       {"box3d", ins.box3d},
                       {"files",
                        {{"with_object_hdr", "insert_with_object_hdr.exr"},
                         {"with_object_ldr", "insert_with_object_ldr.png"},
                         {"without_object_hdr", "insert_without_object_hdr.exr"},
                         {"object_mask", "insert_object_mask.png"}}}};
        if (c.light_probe) {
          // The light at the object: a panorama from its bounding box's centre, without it.
          const Bounds3 b = placed.bounds();
          const glm::dvec3 centre = 0.5 * (glm::dvec3(b.lo) + glm::dvec3(b.hi));
          PathTracerOptions o = opt;
          o.seed = hash_counter(c.seed, static_cast<uint64_t>(index), kProbeSeed);
          const PanoramaRender probe = render_panorama(tracer, centre, c.pano_height, c.pano_width, o);
          write_image(file("insert_light_probe_hdr.exr"), probe.radiance);
          object_meta["files"]["light_probe_hdr"] = "insert_light_probe_hdr.exr";
          object_meta["light_probe_position"] = vec3_json(centre);
        }
        result.has_insertion = true;
      }
    }

    json meta = {{"format", "streetlight-sample"},
                 {"version", 1},
                 {"id", result.id},
                 {"index", index},
                 {"sun_direction", vec3_json(light.sun_direction)},
                 {"lighting", light.meta},
                 {"exposure", exposure},
                 {"ldr", "clip((exposure*L)^(1/2.2), 0, 1)"},
                 {"render",
                  {{"spp", c.spp},
                   {"max_depth", c.max_depth},
                   {"environment_width", c.environment_width},
                   {"target_noise", c.target_noise},
                   {"images", noise_meta}}},
                 {"scene",
                  {{"road_half_width_m", scene.road_half_width_m},
                   {"sidewalk_width_m", scene.sidewalk_width_m},
                   {"triangles", scene.mesh.triangle_count()}}},
                 {"panorama",
                  {{"position", vec3_json(pano_pos)},
                   {"width", c.pano_width},
                   {"height", c.pano_height},
                   {"files", {{"hdr", "pano_hdr.exr"}, {"ldr", "pano_ldr.png"}, {"sky_mask", "pano_sky_mask.png"}}}}},
                 {"sky", {{"file", "sky_hdr.exr"}, {"width", c.sky_width}, {"height", c.sky_height}}},
                 {"views", view_meta},
                 {"object", object_meta}};
    write_file_atomic(file("meta.json"), meta.dump(2) + "\n");

    sample_dir.commit();
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

DatasetSplits split_ids(const std::vector<std::string>& ids, uint64_t seed, double train_fraction,
                        double val_fraction) {
  std::vector<std::string> order = ids;
  Rng rng(seed, 0x5B117);
  for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[static_cast<size_t>(rng.randint(i))]);
  const size_t n = order.size();
  const size_t n_train = static_cast<size_t>(std::llround(train_fraction * n));
  const size_t n_val = std::min(n - n_train, static_cast<size_t>(std::llround(val_fraction * n)));
  DatasetSplits s;
  s.train.assign(order.begin(), order.begin() + n_train);
  s.val.assign(order.begin() + n_train, order.begin() + n_train + n_val);
  s.test.assign(order.begin() + n_train + n_val, order.end());
  for (auto* v : {&s.train, &s.val, &s.test}) std::sort(v->begin(), v->end());
  return s;
}

void write_dataset_index(const std::string& out_dir, const StreetGeneratorConfig& c, const DatasetSplits& s) {
  const json index = {{"format", "streetlight-dataset"},
                      {"version", 1},
                      {"seed", c.seed},
                      {"config", c.tree},
                      {"splits", {{"train", s.train}, {"val", s.val}, {"test", s.test}}}};
  write_file_atomic((fs::path(out_dir) / "index.json").string(), index.dump(2) + "\n");
}

}  // namespace sl::data
