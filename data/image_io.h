// Image and depth-map files through OpenImageIO.
//
// Images are sl::Tensor of shape [C, H, W], dtype F32, row 0 at the top. The format follows the
// file extension: .exr and .hdr hold float radiance; .png (8 or 16 bit) and .jpg/.jpeg (8 bit)
// hold integers. Transfer decides how integer codes map to floats:
//   Auto   — float files as stored; integer files are sRGB-encoded, decoded to linear with the
//            exact piecewise sRGB curve (IEC 61966-2-1). Alpha is never curve-mapped.
//   Linear — no curve: integer codes normalised to [0, 1] (code / (2^bits − 1)).
//   SRGB   — the sRGB curve on colour channels even for float files.
// Writing inverts the same mapping; integer files clamp to [0, 1] and round to nearest, and
// NaN is written as 0. PNG alpha is read and written unassociated (as stored in the file).
//
// Depth maps are [1, H, W] metres (camera-frame z). Single-channel EXR stores metres as float;
// 16-bit PNG is the KITTI convention: metres = code / 256, code 0 = missing. Missing depth is
// returned as 0 by default (the KITTI convention, safe in arithmetic) or NaN on request; when
// writing, 0, negative, NaN and ±Inf all mean missing (code 0 in PNG, NaN in EXR).
//
// Camera photos (JPEG, TIFF) may store the sensor's rows with an EXIF Orientation tag (1-8) that
// says how a viewer turns them: a phone held upright writes 6 (0th row on the right). read_image
// returns the stored rows unless ImageReadOptions::upright, which applies the tag (mirrors and
// quarter turns, exact), so the tensor is the picture as a viewer shows it and its width and height
// are the viewer's. The size check (width, height) then applies to the upright picture.
// read_image_info reports the tag and the EXIF 35 mm-equivalent focal length (0 when absent).
//
// Writes go to a temporary file in the destination folder, renamed over the destination only
// after the whole image was written, so a failure never leaves a partial file.
//
// Throws sl::Error naming the file and the problem for: missing, unreadable, truncated or
// corrupt files; unsupported extensions; channel counts that do not fit the request or the
// format (.hdr needs 3 channels; a depth map needs 1); sizes that differ from the requested
// size; tensors that are not F32/F64 [C, H, W]; and files whose header declares more than
// kMaxImageValues values (width · height · channels), refused before any pixel memory is
// allocated, so a tiny hostile header cannot claim gigabytes (reading costs 8 bytes per value).
// An OpenEXR file whose data window alone is past the limit is refused before OpenEXR opens it
// (data/exr_header.h), by read_image_info too.
#pragma once
#include <cstdint>
#include <string>

#include "autodiff/tensor.h"

namespace sl::data {

enum class Transfer { Auto, Linear, SRGB };

// 2^28 values: a 16384 × 16384 RGBA image, 2 GiB while reading.
inline constexpr int64_t kMaxImageValues = int64_t{1} << 28;

struct ImageReadOptions {
  Transfer transfer = Transfer::Auto;
  // 0 keeps the file's channels. 3 accepts RGB, drops alpha of RGBA and replicates grey;
  // 1 accepts only single-channel files; 4 accepts only RGBA.
  int channels = 0;
  // 0 accepts any size; otherwise the file must have exactly this size.
  int width = 0, height = 0;
  // Apply the file's EXIF Orientation tag (see above); false: the stored rows.
  bool upright = false;
};

struct ImageWriteOptions {
  Transfer transfer = Transfer::Auto;
  int bits = 8;  // PNG: 8 or 16; JPEG: 8; ignored for float formats
};

struct ImageInfo {
  int width = 0, height = 0, channels = 0;
  bool is_float = false;  // float or half pixels (EXR, HDR)
  int bits = 0;           // bits per channel as stored
  int orientation = 1;    // EXIF Orientation, 1-8 (1 when absent or out of range); width, height as stored
  double focal_35mm = 0;  // EXIF FocalLengthIn35mmFilm in mm, 0 when absent
};

// The size of the picture upright: width and height swapped for orientations 5-8.
inline bool orientation_swaps_axes(int orientation) { return orientation >= 5 && orientation <= 8; }

ImageInfo read_image_info(const std::string& path);
Tensor read_image(const std::string& path, const ImageReadOptions& options = {});
void write_image(const std::string& path, const Tensor& image, const ImageWriteOptions& options = {});

enum class MissingDepth { Zero, NaN };
Tensor read_depth(const std::string& path, MissingDepth missing = MissingDepth::Zero, int width = 0,
                  int height = 0);
void write_depth(const std::string& path, const Tensor& depth_m);

// The exact sRGB transfer functions on [0, 1] (linear segment below 0.04045 / 0.0031308).
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);

}  // namespace sl::data
