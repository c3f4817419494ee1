// Turns street-dataset samples (data/street_dataset.h) into what the lighting predictor and
// its losses consume (Sec 3.4, "Supervision for Hybrid Lighting Prediction").
//
// Canonical frame: the predictor cannot know the world's absolute azimuth from one photo, so
// every sample is expressed in the frame of its input camera: world rotated about +Y so the
// camera looks at azimuth 0 (−Z), and translated so the camera sits at (0, y_cam, 0) over the
// world's ground (y = 0 stays the ground). Panoramas are rolled with rotate_azimuth, directions
// and positions rotated with the same rotation. The VSG grid is centred on the camera.
//
// Per sample (all targets in exposure-normalised units, sky_autoencoder.h):
//   image   [3, h, w]       the input view's LDR, bilinearly resized to the model input
//   rgba    [4, X, Y, Z]    unproject_rgba of the input view with its depth (full resolution)
//   pano_ldr_dome [3, Hs, Ws], pano_mask_dome [1, Hs, Ws]: the panorama and its sky mask at the
//           dome size (area-resized; the mask is 1 where at least half the texel is sky)
//   sun_direction           canonical
//   rays: origins/directions [R, 3], target LDR [R, 3], target distance along the ray [R]
//         (NaN where unknown: panorama rays and sky pixels), sky [R] (0/1)
//         — data.pano_rays from the panorama, data.view_rays from the views (all of them).
// Ray choice is a pure function of (seed, stream).
#pragma once
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "data/street_dataset.h"
#include "render/camera.h"
#include "render/vsg_volume.h"

namespace sl::train {

// Rotation about +Y by −yaw and the translation that put the camera at (0, y, 0).
struct CanonicalFrame {
  double yaw_rad = 0.0;  // the input camera's azimuth in the world
  glm::dvec3 camera_world{0.0};
  glm::dvec3 point(const glm::dvec3& world) const;      // world → canonical position
  glm::dvec3 direction(const glm::dvec3& world) const;  // world → canonical direction
  render::Camera camera(const render::Camera& world_camera) const;  // a camera re-expressed in the frame
  Tensor panorama(const Tensor& world_pano) const;      // rolled so world azimuth yaw → 0
  // An object's yaw about +Y (render/object_insertion.h, data/object_placement.h: +X turns toward
  // −Z as yaw grows) re-expressed in the frame. The frame turns the world by +yaw_rad about +Y
  // (azimuth, measured the other way round, drops by yaw_rad), so an object's yaw GROWS by it.
  double object_yaw_deg(double world_yaw_deg) const;
};

CanonicalFrame canonical_frame(const render::Camera& input_camera);

struct StreetBatchOptions {
  int64_t image_height = 128, image_width = 256;
  int64_t dome_height = 32, dome_width = 128;
  int64_t pano_rays = 512, view_rays = 512;
  bool need_volume = true;
};

struct StreetItem {
  CanonicalFrame frame;
  render::Camera camera;  // the input view's camera in the canonical frame
  render::VsgGrid grid;
  Tensor image, rgba, pano_ldr_dome, pano_mask_dome;
  glm::dvec3 sun_direction{0.0, 1.0, 0.0};
  // The sun's energy Σ L·Ω within 5° of the true sun in the HDR sky, exposure-normalised
  // (data/panorama_sample.h sun_energy_rgb); known when the sun is and the sky is HDR.
  glm::dvec3 sun_energy{0.0};
  bool sun_energy_known = false;
  Tensor origins, directions, target_ldr, target_distance, sky;
};

// `grid_template` gives dims and extents; its centre is replaced by the camera's position.
StreetItem make_street_item(const data::StreetSample& sample, size_t input_view, const render::VsgGrid& grid_template,
                            const StreetBatchOptions& options, uint64_t seed, uint64_t stream);

// Bilinear resize of an image [C, H, W] (align_corners = false, as torch's interpolate).
Tensor resize_bilinear(const Tensor& image, int64_t height, int64_t width);

}  // namespace sl::train
