#include "tools/common/insert_options.h"

#include "train/object_labels.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "data/procedural_car.h"
#include "render/gltf_loader.h"
#include "util/error.h"

namespace sl::cli {

namespace fs = std::filesystem;

render::Mesh load_object(const std::string& spec) {
  if (spec == "procedural:car") return data::to_object_frame(data::make_procedural_car());
  SL_CHECK(fs::exists(spec), "object file '", spec, "' does not exist");
  return data::to_object_frame(render::load_gltf(spec));
}


std::vector<std::string> object_classes(const Args& a, size_t objects) {
  if (!a.has("--class")) return std::vector<std::string>(objects, "Car");
  const std::vector<std::string> given = a.all("--class");
  SL_CHECK(given.size() == 1 || given.size() == objects, "--class was given ", given.size(), " times for ", objects,
           " objects: give it once (for every object) or once per --object, in the same order");
  for (const auto& c : given) train::check_kitti_class(c, "--class");
  return given.size() == 1 ? std::vector<std::string>(objects, given[0]) : given;
}

train::PhotoInsertionOptions insertion_options(const Args& a, const render::RadianceQueryOptions& volume_query) {
  train::PhotoInsertionOptions o = a.has("--fast") ? train::fast_insertion_options() : train::PhotoInsertionOptions{};
  o.aa_samples = static_cast<int>(a.integer("--aa", o.aa_samples));
  o.light_samples = static_cast<int>(a.integer("--light-samples", o.light_samples));
  o.shadow_rays = static_cast<int>(a.integer("--shadow-rays", o.shadow_rays));
  o.shadow_width = static_cast<int>(a.integer("--shadow-width", o.shadow_width));
  o.shadow_height = static_cast<int>(a.integer("--shadow-height", o.shadow_height));
  o.adaptive_light_samples = a.number("--adaptive-samples", o.adaptive_light_samples);
  o.denoise_radius = static_cast<int>(a.integer("--denoise-radius", o.denoise_radius));
  o.exact_light_rays = static_cast<int>(a.integer("--exact-light-rays", o.exact_light_rays));
  o.shadow_exact_rays = static_cast<int>(a.integer("--exact-shadow-rays", o.shadow_exact_rays));
  o.radiance_cache = !a.has("--exact");
  o.seed = static_cast<uint64_t>(a.integer("--seed", 0));
  o.volume_query = volume_query;
  SL_CHECK(o.aa_samples > 0 && o.light_samples > 0 && o.shadow_rays > 0 && o.shadow_width > 0 && o.shadow_height > 0,
           "--aa, --light-samples, --shadow-rays, --shadow-width and --shadow-height must be positive");
  SL_CHECK(std::isfinite(o.adaptive_light_samples) && o.adaptive_light_samples >= 0 && o.adaptive_light_samples <= 1024,
           "--adaptive-samples must be in [0, 1024], got ", o.adaptive_light_samples);
  SL_CHECK(o.denoise_radius >= 0 && o.denoise_radius <= 16, "--denoise-radius must be in [0, 16], got ", o.denoise_radius);
  SL_CHECK(o.exact_light_rays >= 0 && o.exact_light_rays <= 64, "--exact-light-rays must be in [0, 64], got ",
           o.exact_light_rays);
  SL_CHECK(o.shadow_exact_rays >= 0 && o.shadow_exact_rays <= 64, "--exact-shadow-rays must be in [0, 64], got ",
           o.shadow_exact_rays);
  return o;
}


void configure_estimator(train::LightingEstimator& est, const Args& a) {
  est.set_flip_average(!a.has("--no-flip-average"));
  est.set_visible_sun(!a.has("--no-visible-sun"));
  if (!a.has("--no-visible-sun") && !a.has("--no-sun-glare")) {
    const std::string glare = a.has("--sun-glare") ? a.get("--sun-glare") : released_sun_glare_path();
    if (!glare.empty()) est.set_sun_glare(train::load_sun_glare(glare));
  }
  est.set_crop_scales(a.numbers("--crop-scales", {}, 0.0, 1.0));
}


void warn_if_no_shadow_sun(const data::ShadowSunFit& fit, const std::string& depth_source, const std::string& frame) {
  if (fit.found) return;
  std::fprintf(stderr, "warning: --sun-from-shadows found no shadow the depth explains%s%s (score %.2f, %d ground "
               "samples, depth: %s); keeping the network's sun\n", frame.empty() ? "" : " in ", frame.c_str(), fit.score,
               fit.ground_samples, depth_source.c_str());
}

void note_if_sun_is_a_guess(double sun_probability, const std::string& depth_source) {
  if (!(sun_probability < kSunGuessProbability)) return;  // also NaN: no sun head
  const bool geometry = depth_source == "lidar" || depth_source == "depth-file" || depth_source == "dataset";
  std::fprintf(stderr, "note: the sun's direction is the model's guess (it gives it probability %.2f of lying within "
               "20°); %s\n", sun_probability,
               geometry ? "--sun-from-shadows reads it from the photo's own shadows"
                        : "--sun-azimuth and --sun-elevation set it by hand, or --lidar/--depth with --sun-from-shadows "
                          "reads it from the photo's shadows");
}

}  // namespace sl::cli
