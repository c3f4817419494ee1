// The rows of streetlight-bench insert's production table (see insert_rows.h).
#include "tools/bench/insert_rows.h"

#include <algorithm>
#include <tuple>

namespace sl::bench {

using render::InsertionOptions;

std::vector<InsertRow> insert_rows(const train::PhotoInsertionOptions& production, bool quick) {
  std::vector<InsertRow> rows;
  rows.push_back({"production", train::insertion_options(production)});
  if (!quick) {
    // streetlight-insert --fast (train/photo_insertion.h fast_insertion_options): the production
    // defaults without the exact corrections, at N = 6 and 128 shadow rays.
    rows.push_back({"fast", train::insertion_options(train::fast_insertion_options())});
    // Eq. 2's diffuse control variate: off, and its two knobs (normal grid, quadrature).
    InsertionOptions plain = train::insertion_options(production);
    plain.diffuse_control_variate = false;
    rows.push_back({"no_control_variate", plain});
    for (int hn : {16, 32, 64, 256}) {
      InsertionOptions o = train::insertion_options(production);
      o.cv_normals_height = hn;
      rows.push_back({"cv_normals" + std::to_string(hn), o});
    }
    InsertionOptions q2 = train::insertion_options(production);
    q2.cv_quadrature_supersample = 2;
    rows.push_back({"cv_quadrature2", q2});
    // The object's probe grid: the former default (1 m, up to 4×3×4, 32×64 directions).
    InsertionOptions coarse = train::insertion_options(production);
    coarse.cache_spacing_m = 1.0;
    coarse.cache_max_y = 3;
    coarse.cache_height = 32;
    coarse.cache_width = 64;
    rows.push_back({"cache_4x3x4_1m", coarse});
    for (int n : {8, 24}) {
      InsertionOptions o = train::insertion_options(production);
      o.light_samples = n;
      rows.push_back({"cv_light" + std::to_string(n), o});
    }
    // Adaptive sampling and the residual filter: each off, and the former N = 16 with and without
    // the filter; then the knobs (base N and average extra samples; the filter's radius).
    InsertionOptions denoise_off = train::insertion_options(production);
    denoise_off.denoise_radius = 0;
    rows.push_back({"denoise_off", denoise_off});
    InsertionOptions adaptive_off = train::insertion_options(production);
    adaptive_off.adaptive_light_samples = 0;
    rows.push_back({"adaptive_off", adaptive_off});
    for (int radius : {0, 2}) {
      InsertionOptions o = train::insertion_options(production);
      o.light_samples = 16;
      o.adaptive_light_samples = 0;
      o.denoise_radius = radius;
      rows.push_back({radius == 0 ? "light16_plain" : "light16_denoise", o});
    }
    for (const auto& [n, a] : std::vector<std::pair<int, int>>{{8, 2}, {8, 4}, {6, 4}, {12, 4}, {16, 8}}) {
      InsertionOptions o = train::insertion_options(production);
      o.light_samples = n;
      o.adaptive_light_samples = a;
      rows.push_back({"adaptive_light" + std::to_string(n) + "_plus" + std::to_string(a), o});
    }
    for (int radius : {1, 3}) {
      InsertionOptions o = train::insertion_options(production);
      o.denoise_radius = radius;
      rows.push_back({"denoise_radius" + std::to_string(radius), o});
    }
    InsertionOptions no_variance_guide = train::insertion_options(production);
    no_variance_guide.denoise_variance_sigma = 0;
    rows.push_back({"denoise_no_variance_guide", no_variance_guide});
  }
  if (!quick) {
    InsertionOptions exact = train::insertion_options(production);
    exact.radiance_cache = false;
    rows.push_back({"production_exact_queries", exact});
    // One pass of the reference (bench_insert.cpp: exact queries, 64 light samples per primary
    // sample, 256 shadow rays, no control variate, adaptive sampling or filter): its noise / √passes
    // is the reference's own noise, which every row's rel_rmse contains.
    InsertionOptions ref_pass = exact;
    ref_pass.light_samples = 64;
    ref_pass.shadow_rays = 256;
    ref_pass.diffuse_control_variate = false;
    ref_pass.adaptive_light_samples = 0;
    ref_pass.denoise_radius = 0;
    rows.push_back({"reference_pass", ref_pass});
    InsertionOptions texel_env = train::insertion_options(production);
    texel_env.bilinear_env_sampling = false;
    rows.push_back({"texel_env_sampling", texel_env});
    InsertionOptions per_pixel = train::insertion_options(production);  // the default until 2026-11-27
    per_pixel.stratify_per_pixel = true;
    rows.push_back({"strata_per_pixel", per_pixel});
    for (int n : {8, 16, 32}) {
      InsertionOptions o = train::insertion_options(production);
      o.light_samples = n;
      o.shadow_rays = 4 * n;
      rows.push_back({"light" + std::to_string(n), o});
    }
    for (const auto& [h, w, sp] : std::vector<std::tuple<int, int, double>>{{64, 128, 2.0}, {32, 64, 1.0}, {64, 128, 1.0}}) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_height = h;
      o.cache_width = w;
      o.cache_spacing_m = sp;
      rows.push_back({"cache" + std::to_string(w) + "x" + std::to_string(h) + "_" + std::to_string(int(sp)) + "m", o});
    }
    // A finer probe grid over the object only (the light rays'), up to 8×4×8 probes 1 m apart.
    for (const auto& [sp, xz, y] : std::vector<std::tuple<double, int, int>>{{1.0, 8, 4}, {0.5, 12, 6}}) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_spacing_m = sp;
      o.cache_max_xz = xz;
      o.cache_max_y = y;
      rows.push_back({"cache_object_" + std::to_string(xz) + "x" + std::to_string(y) + "x" + std::to_string(xz), o});
    }
    // The object's probes finer in space, coarser in direction (the object's error is spatial:
    // cache128x64_* leave it where it is). Released lighting, KITTI (2026-11-27): 12×24
    // directions 1.15%, 16×32 0.98% (as 24×48); 0.35 m apart (16×8×16) with 12×24 also 0.98%,
    // with 8×16 1.21%: a floor near 0.9% bias that spacing alone does not lower.
    // An object probe grid: hd × 2hd directions, probes sp metres apart, at most xz × y × xz.
    const auto object_grid = [&](const std::string& prefix, bool sparse, int hd, double sp, int xz, int y) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_sparse = sparse;
      o.cache_height = hd;
      o.cache_width = 2 * hd;
      o.cache_spacing_m = sp;
      o.cache_max_xz = xz;
      o.cache_max_y = y;
      rows.push_back({prefix + std::to_string(xz) + "x" + std::to_string(y) + "x" + std::to_string(xz) + "_dirs" +
                          std::to_string(hd) + "x" + std::to_string(2 * hd),
                      o});
    };
    for (const auto& [hd, sp, xz, y] : std::vector<std::tuple<int, double, int, int>>{{12, 0.5, 12, 6}, {16, 0.5, 12, 6}})
      object_grid("cache_object_", train::insertion_options(production).cache_sparse, hd, sp, xz, y);
    // Sparse probe grids (only cells that hold an origin), then finer object grids on them.
    // Released lighting, KITTI, OMP_NUM_THREADS=1 under load (2026-11-27), object term / CPU
    // against production's 1.24% / ~1.15 s: 8×6×8 1.14% +18%; 0.5 m 16×32 directions 0.98%
    // +35%, 24×48 0.98%, 32×64 0.97%; 0.35 m 16×32 0.91% +76%, 24×48 0.87% +120%. The
    // random-stress volume: 1.88% → 0.94% at 0.5 m 16×32. Spacing, not directions, sets it.
    for (const auto& [hd, sp, xz, y] : std::vector<std::tuple<int, double, int, int>>{
             {24, 1.0, 4, 6}, {24, 1.0, 8, 6}, {16, 0.5, 12, 6}, {24, 0.5, 12, 6}, {32, 0.5, 12, 6}, {16, 0.35, 16, 8},
             {24, 0.35, 16, 8}, {12, 0.25, 24, 12}})
      object_grid("sparse_object_", true, hd, sp, xz, y);
    for (int n : {128, 256}) {  // shadow rays alone (the shadow term is mostly noise)
      InsertionOptions o = train::insertion_options(production);
      o.shadow_rays = n;
      rows.push_back({"shadow" + std::to_string(n), o});
    }
    for (int rays : {64, 128, 256})  // the shadow rays' probe grid (default 2×2×2)
      for (int xz : {4, 8}) {
        InsertionOptions o = train::insertion_options(production);
        o.shadow_rays = rays;
        o.cache_shadow_max_xz = xz;
        o.cache_spacing_m = 1.0;
        rows.push_back({"shadow" + std::to_string(rays) + "_grid" + std::to_string(xz) + "x2x" + std::to_string(xz), o});
      }
    for (const auto& [xz, hs] : std::vector<std::pair<int, int>>{{4, 24}, {8, 6}, {8, 24}}) {  // the shadow grid
      InsertionOptions o = train::insertion_options(production);
      o.cache_shadow_max_xz = xz;
      o.cache_shadow_height = hs;
      rows.push_back({"shadow_grid" + std::to_string(xz) + "x2x" + std::to_string(xz) + "_dirs" + std::to_string(hs) +
                          "x" + std::to_string(2 * hs),
                      o});
    }
    // Shadow rays toward bright sky (the sun) marched exactly (render/object_insertion.h,
    // cache_shadow_exact_sky, default 8): the threshold over the sky's mean (0 = all cached),
    // then with a coarser shadow grid and more shadow rays, then finer shadow grids beside it.
    {  // the defaults before them: every shadow ray cached, dense probe grids
      InsertionOptions o = train::insertion_options(production);
      o.cache_shadow_exact_sky = 0;
      o.cache_sparse = false;
      rows.push_back({"former_cache_defaults", o});
    }
    for (double t : {0.0, 20.0, 8.0, 3.0, 1.0}) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_shadow_exact_sky = t;
      rows.push_back({"shadow_exact_sky" + std::to_string(int(t)), o});
    }
    for (const auto& [t, rays, xz] : std::vector<std::tuple<double, int, int>>{{3.0, 128, 4}, {3.0, 256, 8}, {3.0, 256, 4}}) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_shadow_exact_sky = t;
      o.shadow_rays = rays;
      o.cache_shadow_max_xz = xz;
      rows.push_back({"shadow_exact_sky" + std::to_string(int(t)) + "_rays" + std::to_string(rays) + "_grid" +
                          std::to_string(xz) + "x2x" + std::to_string(xz),
                      o});
    }
    for (const auto& [t, xz, hs] : std::vector<std::tuple<double, int, int>>{{8.0, 16, 12}, {8.0, 16, 6}, {8.0, 12, 8}}) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_shadow_exact_sky = t;
      o.cache_shadow_max_xz = xz;
      o.cache_shadow_height = hs;
      rows.push_back({"shadow_exact_sky" + std::to_string(int(t)) + "_grid" + std::to_string(xz) + "x2x" +
                          std::to_string(xz) + "_dirs" + std::to_string(hs) + "x" + std::to_string(2 * hs),
                      o});
    }
    // Exact corrections (render/object_insertion.h, "Exact corrections"): M exact rays per
    // object sample (filtered over (2r+1)² pixels) and per shadow texel (over (2r+1)² texels),
    // each alone, then with the probe and sample knobs that bring the row under 1%.
    struct Corrected {
      const char* name;
      double spacing;
      int dirs, xz, light, exact_light, light_radius, shadow_rays, exact_shadow, shadow_radius;
    };
    for (const Corrected& c : std::vector<Corrected>{
             {"former_production", 1.0, 24, 4, 6, 0, 0, 128, 0, 0},  // until 2026-11-27
             {"exact_light1_unfiltered", 1.0, 24, 4, 6, 1, 0, 128, 0, 0},
             {"exact_light1", 1.0, 24, 4, 6, 1, 8, 128, 0, 0},
             {"exact_light2", 1.0, 24, 4, 6, 2, 8, 128, 0, 0},
             {"exact_light6_all_unfiltered", 1.0, 24, 4, 6, 6, 0, 128, 0, 0},
             {"exact_shadow16_unfiltered", 1.0, 24, 4, 6, 0, 0, 128, 16, 0},
             {"exact_shadow16", 1.0, 24, 4, 6, 0, 0, 128, 16, 2},
             {"exact_shadow16_rays256", 1.0, 24, 4, 6, 0, 0, 256, 16, 2},
             {"exact_light1_shadow16_rays256", 1.0, 24, 4, 6, 1, 8, 256, 16, 2},
             {"exact_light1_n8_shadow16_rays256", 1.0, 24, 4, 8, 1, 8, 256, 16, 2},
             {"exact_light2_n8_shadow16_rays256", 1.0, 24, 4, 8, 2, 6, 256, 16, 2},
             {"exact_light2_n8_probes0.5m_shadow16_rays256", 0.5, 16, 12, 8, 2, 4, 256, 16, 2},
         }) {
      InsertionOptions o = train::insertion_options(production);
      o.cache_spacing_m = c.spacing;
      o.cache_height = c.dirs;
      o.cache_width = 2 * c.dirs;
      o.cache_max_xz = c.xz;
      o.light_samples = c.light;
      o.cache_exact_light_rays = c.exact_light;
      o.cache_exact_filter_radius = c.light_radius;
      o.shadow_rays = c.shadow_rays;
      o.cache_shadow_exact_rays = c.exact_shadow;
      o.cache_shadow_exact_filter_radius = c.shadow_radius;
      rows.push_back({c.name, o});
    }
    // The object's bias taken apart (run with --bias-runs): production less one approximation at
    // a time, down to a row with no cache read left uncorrected, no filter and plain Eq. 2 (whose
    // mean is the reference's).
    struct Ablation {
      const char* name;
      bool residual_filter, correction_filter, all_exact, control_variate, fine_e;
    };
    for (const Ablation& a : std::vector<Ablation>{
             {"bias_no_residual_filter", false, true, false, true, false},
             {"bias_no_correction_filter", true, false, false, true, false},
             {"bias_no_filters", false, false, false, true, false},
             {"bias_no_filters_fine_e", false, false, false, true, true},
             {"bias_all_exact_no_filters", false, false, true, true, false},
             {"bias_all_exact_no_filters_fine_e", false, false, true, true, true},
             {"bias_all_exact_plain", false, false, true, false, false},
         }) {
      InsertionOptions o = train::insertion_options(production);
      if (!a.residual_filter) o.denoise_radius = 0;
      if (!a.correction_filter) o.cache_exact_filter_radius = 0;
      if (a.all_exact) {
        // Every light sample marched exactly: N·(1 + adaptive factor) per primary sample, within
        // insert_objects' limit of 64 exact rays (N = 16: the adaptive factor drops from 8 to 3).
        constexpr int kMaxExactLightRays = 64;
        o.adaptive_max_factor = std::min(o.adaptive_max_factor, std::max(0, kMaxExactLightRays / o.light_samples - 1));
        o.cache_exact_light_rays = std::min(kMaxExactLightRays, o.light_samples * (1 + o.adaptive_max_factor));
      }
      o.diffuse_control_variate = a.control_variate;
      if (!a.control_variate) o.denoise_radius = 0;
      if (a.fine_e) {
        o.cv_normals_height = 256;
        o.cv_quadrature_supersample = 2;
      }
      rows.push_back({a.name, o});
    }
    {  // the measured knobs together: object probes 8×4×8, 256 shadow rays over a 4×2×4 grid
      InsertionOptions o = train::insertion_options(production);
      o.cache_spacing_m = 1.0;
      o.cache_max_xz = 8;
      o.cache_max_y = 4;
      o.shadow_rays = 256;
      o.cache_shadow_max_xz = 4;
      rows.push_back({"object8x4x8_shadow256_grid4x2x4", o});
    }
  }
  return rows;
}

}  // namespace sl::bench
