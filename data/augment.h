// Training-time augmentation of street samples and panoramas.
//
// - random_perspective_crop: a seeded perspective crop of a panorama (data/panorama.h
//   crop_perspective) with field of view, yaw, pitch and roll drawn from ranges; returns the
//   crop's camera (centre at `position`), so depth, directions and pixels stay consistent.
// - Horizontal flips mirror the world, not just the pixels. Flipping a view mirrors the world
//   across the camera's own vertical plane (spanned by its y and z axes): a point at camera
//   coordinates (x, y, z) moves to (−x, y, z), which is the flipped pixel u → W − u. The camera
//   pose stays; the principal point becomes cx → W − cx; world directions d (the sun) become
//   d − 2(d·a)a with a the camera's x axis in the world. Depth (camera z) is flipped with the
//   pixels and keeps its values. Flipping a panorama mirrors azimuth φ → −φ, i.e. world
//   (x, y, z) → (−x, y, z) (render/equirect.h), the same rule as a view looking down −Z.
// - Exposure jitter scales linear HDR by k = 2^s, s uniform in [−stops, stops]; for LDR that
//   was made as clip((e·L)^(1/2.2)) the same change is clip(k^(1/2.2)·LDR) (exact where the
//   LDR was not clipped).
// Randomness is a pure function of (seed, stream) (util/random.h).
// Throws: sl::Error naming the function and the offending shape or range.
#pragma once
#include <cstdint>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "data/panorama.h"
#include "data/street_dataset.h"

namespace sl::data {

// Sun-aimed crops. A crop drawn with uniform yaw and pitch within ±10° rarely shows the sun (0.6% of
// the training LDR crops with a labelled sun: suns stand 35-50° high and a 2:1 view reaches about
// 20° above its axis). With a sun direction given and probability sun_aim_share, a crop is aimed:
// half of the aimed crops look TOWARD the sun (it lies in the view, within 70% of the half field
// of view from its centre, the pitch within ±sun_aim_max_pitch_deg) and half look AWAY from it (the
// yaw turned by 180°, the pitch as drawn), so the share of suns in front of the camera is
// unchanged. A sun too high to be brought into view at that pitch leaves the crop as drawn (both
// halves alike). The draws for the aim are made after the others, so the other parameters of a
// crop, and every crop of sun_aim_share = 0, are those of the plain draw.
struct CropRanges {
  double fov_min_deg = 50.0, fov_max_deg = 80.0;
  double pitch_range_deg = 10.0;  // pitch uniform in [−range, range]
  double roll_range_deg = 0.0;
  int width = 256, height = 128;
  double sun_aim_share = 0.0;          // probability of an aimed crop (needs a sun direction)
  double sun_aim_max_pitch_deg = 25.0;
};

struct RandomCrop {
  PerspectiveCrop crop;  // image [C, height, width] and its camera
  double fov_deg = 0.0, yaw_deg = 0.0, pitch_deg = 0.0, roll_deg = 0.0;
  int aimed = 0;  // +1 toward the sun, −1 away from it, 0 as drawn
};

// sun: the world direction to aim at (nullptr: never aimed).
RandomCrop random_perspective_crop(const Tensor& pano, uint64_t seed, uint64_t stream, const CropRanges& ranges = {},
                                   const glm::dvec3& position = glm::dvec3(0.0), const glm::dvec3* sun = nullptr);
// The crop_perspective parameters of a drawn crop at width × height (e.g. to cut the same view
// out of the panorama's sky mask).
PerspectiveCropParams crop_params(const RandomCrop& crop, int width, int height);

// Reverses the last dimension of a [C, H, W] or [H, W] tensor (F32), returning a new tensor.
Tensor flip_horizontal(const Tensor& image);

// d − 2(d·n)n for a unit normal n.
glm::dvec3 mirror_direction(const glm::dvec3& d, const glm::dvec3& unit_normal);

// Flips every image of the view and mirrors its camera's principal point (see above). When
// `world_direction` is given (e.g. the sun), it is mirrored across the same plane.
StreetView flip_view(const StreetView& view, glm::dvec3* world_direction = nullptr);

// Mirrors a whole street sample across the world plane x = 0 (every view, panorama, position
// and the sun), so that several views stay consistent with one another: a world point X seen by
// view v at pixel (u, y) becomes (−X.x, X.y, X.z), seen by the flipped view v at (W − u, y).
// Each camera becomes R' = M·R·D, t' = M·t (M = D = diag(−1, 1, 1): a proper rotation again)
// with cx' = W − cx; panoramas are flip_panorama'd. The insertion data is dropped
// (has_insertion = false, box2d/box3d zeroed): a mirrored object is not the .glb's object.
// Flipping twice gives the sample back.
StreetSample flip_sample(const StreetSample& sample);

// Panorama flip: pixels mirrored (φ → −φ) and directions (x, y, z) → (−x, y, z).
Tensor flip_panorama(const Tensor& pano);
inline glm::dvec3 flip_panorama_direction(const glm::dvec3& d) { return {-d.x, d.y, d.z}; }

// 2^s with s uniform in [−stops, stops].
double random_exposure_factor(uint64_t seed, uint64_t stream, double stops);
Tensor scale_hdr(const Tensor& hdr, double factor);
Tensor scale_ldr(const Tensor& ldr, double factor);  // clip(factor^(1/2.2)·ldr, 0, 1)

}  // namespace sl::data
