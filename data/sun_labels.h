// Hand-made sun labels of a folder of LDR equirectangular panoramas (../shared/data/pano_ldr/
// sun_labels.csv, MANIFEST.md there): one CSV row per panorama,
//   file,sun,u,v,confidence,scene,note
// sun ∈ {visible, occluded, none}: the disk (or its blown-out core) is in the image; it is hidden
// but the shadows place it; there is none (overcast, shade, dusk). (u, v) are continuous pixel
// coordinates of the sun's centre in the LABEL FRAME (2048×1024 by default, whatever the image's
// own size), given for every visible label and optionally for an occluded one. confidence ∈
// {high, medium, low}; scene ∈ {street, other}; note is free text.
//
// Contract:
// - read_sun_labels(path): RFC 4180 CSV — fields may be quoted ("a, b"), a quote inside quotes
//   is doubled (""), a quoted field may span lines; CRLF or LF; blank lines are skipped. Columns
//   are found by their header name (any order; extra columns are ignored; `note` is optional).
//   Rows keep the file's order; `line` is the row's first line in the file (1-based).
// - Throws sl::Error naming the file and the line (`FILE:LINE`) for: a file that cannot be
//   opened; a header without file, sun, u, v, confidence or scene; a row with fewer or more
//   fields than the header; an unknown sun, confidence or scene value (named, with the allowed
//   ones); a u or v that is not a number, or only one of them; a (u, v) outside the label frame
//   [0, W] × [0, H]; a visible label without a position, or a none label with one; an empty or
//   repeated file name; an unterminated quote; a file without rows.
// - direction(label, W, H): the sun's world unit direction through the project's one
//   equirectangular mapping (render/equirect.h), after scaling (u, v) from the label frame to a
//   W×H image; the same direction for every size, as the mapping is scale-free. Requires
//   has_position.
#pragma once
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace sl::data {

enum class SunVisibility { Visible, Occluded, None };
enum class LabelConfidence { High, Medium, Low };
enum class SceneKind { Street, Other };

const char* to_string(SunVisibility v);
const char* to_string(LabelConfidence c);
const char* to_string(SceneKind s);

struct PanoramaSunLabel {
  std::string file;  // file name inside the panorama folder
  SunVisibility sun = SunVisibility::None;
  bool has_position = false;
  double u = 0.0, v = 0.0;  // label-frame pixels; meaningful only with has_position
  LabelConfidence confidence = LabelConfidence::High;
  SceneKind scene = SceneKind::Street;
  std::string note;
  int line = 0;  // the row's first line in the CSV (1-based)
};

struct SunLabels {
  std::string path;                    // the CSV it was read from
  int frame_width = 2048, frame_height = 1024;  // the label frame (u, v) refer to
  std::vector<PanoramaSunLabel> rows;

  // The label of `file` (a file name), or nullptr.
  const PanoramaSunLabel* find(const std::string& file) const;
  // (u, v) of `label` in a width×height image (scaled from the label frame).
  glm::dvec2 pixel_in(const PanoramaSunLabel& label, int width, int height) const;
  // World unit direction of `label`'s sun (see the contract); throws naming the file and line
  // when the label has no position.
  glm::dvec3 direction(const PanoramaSunLabel& label, int width, int height) const;
};

SunLabels read_sun_labels(const std::string& path, int frame_width = 2048, int frame_height = 1024);

}  // namespace sl::data
