// A visible sun disk in an LDR photo: the explicit cue that points the sun at the ray through it
// (issue 39 item 3; train/inference.h uses it before the sky vector is decoded).
//
// Method: a pixel is clipped when every channel is ≥ `saturation`; the clipped pixels form
// 8-connected components. A component is a sun candidate when it is
//   - of a sun's size: area in [min_area_fraction, max_area_fraction] of the image (an overcast
//     sky, a white facade or a blown-out cloud bank is large; a glint or a lamp small);
//   - compact: area / (π r_max²) ≥ min_compactness, r_max the largest distance of its pixels
//     from its centroid (+0.5 px) — a disk gives about 1, a 2:1 rectangle 0.5, a cloud edge less;
//   - mostly inside the image: ≤ max_border_fraction of its pixels on the image border;
//   - glowing: the clipped core is surrounded by a halo that falls off outward. With rings of
//     width w = max(2 px, r_max) around the centroid beyond r_max, ring 1 [r_max, r_max + w) and
//     ring 3 [r_max + 2w, r_max + 3w), the halo is bright (mean luminance of ring 1 ≥ min_halo)
//     and falls off (ring 1 − ring 3 ≥ min_falloff). A white wall in shade or under a blue sky has
//     a sharp edge: its ring 1 is neither bright all round nor brighter than ring 3;
//   - in the sky: with a camera, the ray's elevation ≥ min_elevation_deg; without, the centroid
//     in the top max_row_fraction of the image.
// Of the candidates the one with the highest score (= falloff × compactness) wins; the sun is
// found when it exists. Luminance is Rec. 709 of the LDR values themselves (a ranking, not
// radiance). Thresholds were measured on the training and validation crops of the real-sky
// benchmark (HDR and LDR panoramas), never on test crops: see VisibleSunParams.
//
// Requires: an LDR image [3, H, W] (any float dtype), values nominally in [0, 1]; NaN and Inf are
//   treated as 0 (never clipped, never glowing). A camera, when given, matches W×H.
// Guarantees: deterministic; found = false (pixel (0, 0), score 0, direction +Y) for an image
//   without a candidate, including empty, black and uniformly clipped images; pixel is the
//   centroid of the clipped pixels' centres in continuous pixel coordinates (render/camera.h);
//   direction is the unit world ray through it (+Y without a camera); every number is finite.
// Throws: sl::Error naming the shape, the camera's size or the parameter out of range.
#pragma once
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/camera.h"

namespace sl::data {

// Defaults chosen on the real-sky benchmark's TRAIN and VALIDATION crops only (HDR skies exposed
// at median LDR 0.4 and 8-bit LDR panoramas, 256×128: 32 random crops per panorama as the
// benchmark draws them, and 16 crops per hard-sun panorama aimed so the sun falls inside): of
// the random crops whose sun is outside, 11 of 1512 fire wrongly (6 of them garden_nook, a blurry
// 256×128 sky), 11 of 928 sun-less or soft-sun crops fire; 16 of 24 random and 177 of 325 aimed
// sun-in-crop crops fire, all within 5° of the true sun. Missed suns are mostly LDR glare merged
// with clouds (compactness < 0.5) and HDR suns in a dim halo (ring 1 < 0.55).
struct VisibleSunParams {
  double saturation = 0.98;           // every channel ≥ this: clipped
  double min_area_fraction = 0.0018;  // of H·W (60 px at 256×128); smaller: glints, lamps
  double max_area_fraction = 0.06;    // of H·W; larger: overcast, facades, cloud banks
  double min_compactness = 0.5;       // area / (π r_max²)
  double max_border_fraction = 0.1;   // of the component's pixels on the image border
  double min_halo = 0.55;             // mean LDR luminance of ring 1
  double min_falloff = 0.10;          // ring 1 − ring 3 mean luminance
  double min_elevation_deg = -2.0;    // with a camera
  double max_row_fraction = 0.75;     // without a camera: centroid row / H (not tuned: the
                                      // benchmark always has a camera)
};

struct VisibleSun {
  bool found = false;
  glm::dvec2 pixel{0.0};                // continuous (u, v), render/camera.h
  glm::dvec3 direction{0.0, 1.0, 0.0};  // world ray through pixel (camera given), else +Y
  double score = 0.0;                   // falloff × compactness of the winner; 0 when not found
  // The winner's measurements (also for a rejected best candidate when found = false, for
  // diagnostics: candidate_count = 0 when no component exists).
  int area_px = 0;
  double compactness = 0.0, border_fraction = 0.0, halo = 0.0, falloff = 0.0, elevation_deg = 0.0;
  int candidate_count = 0;  // clipped components seen
};

VisibleSun find_visible_sun(const Tensor& ldr, const VisibleSunParams& params = {});
VisibleSun find_visible_sun(const Tensor& ldr, const render::Camera& camera, const VisibleSunParams& params = {});

// Every clipped component's measurements, in scan order of their first pixel, found = whether it
// passes every test above (score 0 otherwise). camera may be null. For diagnostics and tuning.
std::vector<VisibleSun> visible_sun_candidates(const Tensor& ldr, const render::Camera* camera,
                                               const VisibleSunParams& params = {});

}  // namespace sl::data
