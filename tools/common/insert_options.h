// The flags both modes of streetlight-insert share (a single photo, and --batch): the object to
// insert, the insertion's sampling options (train/photo_insertion.h), the estimator's options, the
// warning when --sun-from-shadows finds no shadow to fit, and the note when the sun is a guess.
// Throws: sl::Error naming the flag or the file (exit 2 through cli::run_main).
#pragma once
#include <string>
#include <vector>

#include "data/sun_from_shadows.h"
#include "render/mesh.h"
#include "render/radiance_query.h"
#include "tools/common/cli.h"
#include "train/inference.h"
#include "train/photo_insertion.h"

namespace sl::cli {

// "procedural:car" or a glTF file, in the object frame (data/procedural_car.h, to_object_frame).
render::Mesh load_object(const std::string& spec);
// The KITTI class of each of `objects` objects (train/object_labels.h check_kitti_class): "Car"
// without --class, one --class for all, or one per --object in their order.
std::vector<std::string> object_classes(const Args& a, size_t objects);
// --fast, --aa, --light-samples, --shadow-rays, --shadow-width, --shadow-height,
// --adaptive-samples, --denoise-radius, --exact-light-rays, --exact-shadow-rays, --exact, --seed.
train::PhotoInsertionOptions insertion_options(const Args& a, const render::RadianceQueryOptions& volume_query);
// --no-flip-average, --no-visible-sun, --crop-scales.
void configure_estimator(train::LightingEstimator& est, const Args& a);
// --sun-from-shadows without a confident fit: one warning line on stderr (the network's sun stays).
void warn_if_no_shadow_sun(const data::ShadowSunFit& fit, const std::string& depth_source, const std::string& frame);
// The network's own sun (no edit, no shadow fit, no visible sun) that the network itself gives less
// than kSunGuessProbability of lying within 20° of where it put it (EstimatedLighting::sun_probability):
// one note line on stderr naming the probability and what sets the sun from the photo instead:
// --sun-from-shadows where the photo has real geometry (depth_source "lidar", "depth-file" or
// "dataset"), else --sun-azimuth/--sun-elevation. Nothing for a NaN probability (no sun head) or
// a larger one.
inline constexpr double kSunGuessProbability = 0.5;
void note_if_sun_is_a_guess(double sun_probability, const std::string& depth_source);

}  // namespace sl::cli
