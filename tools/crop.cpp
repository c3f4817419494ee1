// streetlight-crop: a perspective photo cut from an equirectangular panorama, with the intrinsics
// streetlight-insert reads, so an object can be inserted into a view of a 360° street panorama
// (its depth: the ground plane seen from the panorama's height and the view's pitch).
//
// - The panorama: an 8-bit .jpg/.png is read as codes / 255 (the paper's LDR, as the estimator
//   reads a photo) and resampled in linear radiance codes^2.2, then re-encoded (the sample of
//   data/ldr_panorama_sample.h without jitter); an .hdr/.exr is resampled as stored and written
//   as the paper's LDR with its median luminance at 0.4 (the generator's exposure), or as linear
//   EXR when --out ends in .exr.
// - The view: horizontal field of view, yaw (the panorama azimuth of the view's centre,
//   render/equirect.h), pitch (positive up) and roll, as data/panorama.h crop_perspective.
// - --sun-labels (default: sun_labels.csv beside an 8-bit panorama, when it exists) adds the
//   labelled sun's pixel in the view and whether it is inside, to --json.
// Outputs are written atomically. Bad input: one line "error: ..." naming the flag or file, exit 2.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sun_labels.h"
#include "render/exposure.h"
#include "tools/common/cli.h"
#include "util/file.h"
#include "util/file_kind.h"
#include "util/math.h"

namespace {

using namespace sl;
namespace fs = std::filesystem;

int run(int argc, char** argv) {
  cli::Args a("streetlight-crop",
              "streetlight-crop --panorama PANO --out IMG.png|IMG.exr [--intrinsics-out FILE.json] [--yaw DEG]\n"
              "                 [--pitch DEG] [--roll DEG] [--fov DEG] [--width W] [--height H] [--sun-labels FILE] [--json]\n\n"
              "Cuts a perspective photo out of an equirectangular panorama (2:1, row 0 the zenith) and writes the\n"
              "intrinsics JSON {fx, fy, cx, cy, width, height} that streetlight-insert --intrinsics reads. An 8-bit\n"
              "panorama is resampled in linear radiance (codes^2.2) and re-encoded; an HDR one is written as LDR with\n"
              "its median at 0.4, or as linear EXR. Insert into the view with the ground plane at the panorama's\n"
              "height: streetlight-insert --image IMG.png --intrinsics FILE.json --pitch DEG --camera-height H ...",
              {{"--panorama", "FILE", "equirectangular panorama: .jpg/.png (8-bit) or .hdr/.exr"},
               {"--out", "FILE", "the view: .png or .jpg (LDR) or .exr (linear)"},
               {"--intrinsics-out", "FILE", "intrinsics JSON (default: --out with .json)"},
               {"--yaw", "DEG", "panorama azimuth of the view's centre (default 0: the panorama's centre column)"},
               {"--pitch", "DEG", "view pitch, positive up (default 0)"},
               {"--roll", "DEG", "view roll (default 0)"},
               {"--fov", "DEG", "horizontal field of view (default 60)"},
               {"--width", "W", "view width in pixels (default 640)"},
               {"--height", "H", "view height in pixels (default 360)"},
               {"--sun-labels", "FILE", "sun labels (sun_labels.csv format) to locate the labelled sun in the view"},
               {"--json", "", "print the view's camera (and the labelled sun) as JSON on stdout"}});
  if (!a.parse(argc, argv)) return 0;
  SL_CHECK(a.has("--panorama") && a.has("--out"), "--panorama FILE and --out FILE are required");
  const std::string pano_path = a.get("--panorama"), out = a.get("--out");
  SL_CHECK(fs::is_regular_file(pano_path), "--panorama: '", pano_path, "' is not a file");
  const bool out_exr = has_extension(out, {".exr"});
  SL_CHECK(out_exr || has_extension(out, {".png", ".jpg", ".jpeg"}),
           "--out: '", out, "' must end in .png, .jpg or .exr");
  const double fov = a.number("--fov", 60.0), yaw = a.number("--yaw", 0.0), pitch = a.number("--pitch", 0.0),
               roll = a.number("--roll", 0.0);
  SL_CHECK(std::isfinite(fov) && fov > 1.0 && fov < 170.0, "--fov must lie in (1, 170) degrees, got ", fov);
  SL_CHECK(std::isfinite(yaw) && std::isfinite(roll), "--yaw and --roll must be finite");
  SL_CHECK(std::isfinite(pitch) && std::abs(pitch) < 90.0, "--pitch must lie in (-90, 90) degrees, got ", pitch);
  const int width = static_cast<int>(cli::parse_integer("--width", a.get("--width", "640"), 1, 16384));
  const int height = static_cast<int>(cli::parse_integer("--height", a.get("--height", "360"), 1, 16384));

  const bool ldr_input = !has_extension(pano_path, {".hdr", ".exr"});
  data::ImageReadOptions ro;
  ro.channels = 3;
  if (ldr_input) ro.transfer = data::Transfer::Linear;  // codes / 255
  Tensor pano = data::read_image(pano_path, ro).to(DType::F32).contiguous();
  SL_CHECK(pano.size(2) == 2 * pano.size(1), "--panorama: '", pano_path, "' is ", pano.size(2), "x", pano.size(1),
           "; an equirectangular panorama is 2:1 (width = 2 x height)");
  if (ldr_input) pano = pow_scalar(pano, kLdrGamma).contiguous();  // linear radiance, clipped where the camera clipped
  data::PerspectiveCropParams p;
  p.horizontal_fov_rad = fov * kDegToRad;
  p.yaw_rad = yaw * kDegToRad;
  p.pitch_rad = pitch * kDegToRad;
  p.roll_rad = roll * kDegToRad;
  p.width = width;
  p.height = height;
  const data::PerspectiveCrop crop = data::crop_perspective(pano, p);
  const Tensor image = crop.image.contiguous();
  const double exposure = ldr_input ? 1.0 : render::exposure_for_ldr_median(image, 0.4);

  const render::Intrinsics& k = crop.camera.intrinsics();
  nlohmann::json intr{{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"width", k.width}, {"height", k.height}};
  std::string intr_path = a.get("--intrinsics-out");
  if (intr_path.empty()) intr_path = fs::path(out).replace_extension(".json").string();
  SL_CHECK(intr_path != out, "--intrinsics-out must differ from --out");
  nlohmann::json result{{"panorama", pano_path}, {"out", out}, {"intrinsics", intr_path},
                        {"view", {{"yaw_deg", yaw}, {"pitch_deg", pitch}, {"roll_deg", roll}, {"fov_deg", fov}}},
                        {"exposure", exposure}};
  std::string labels_path = a.get("--sun-labels");
  if (labels_path.empty() && ldr_input) {
    const fs::path beside = fs::path(pano_path).parent_path() / "sun_labels.csv";
    if (fs::exists(beside)) labels_path = beside.string();
  }
  if (!labels_path.empty()) {
    const data::SunLabels labels = data::read_sun_labels(labels_path);
    const std::string name = fs::path(pano_path).filename().string();
    const data::PanoramaSunLabel* l = labels.find(name);
    SL_CHECK(l != nullptr, "--sun-labels: '", labels_path, "' has no row for '", name, "'");
    nlohmann::json sun{{"class", data::to_string(l->sun)}, {"confidence", data::to_string(l->confidence)}};
    if (l->has_position) {
      const glm::dvec3 d = labels.direction(*l, static_cast<int>(pano.size(2)), static_cast<int>(pano.size(1)));
      const render::Projection pr = crop.camera.project(crop.camera.position() + 1e3 * d);
      sun["elevation_deg"] = std::asin(std::clamp(d.y, -1.0, 1.0)) / kDegToRad;
      sun["azimuth_deg"] = std::atan2(d.x, -d.z) / kDegToRad;
      sun["in_view"] = pr.in_image;
      if (pr.in_front) sun["pixel"] = {pr.pixel.x, pr.pixel.y};
    }
    result["sun"] = sun;
  }
  if (out_exr) {
    data::write_image(out, image);
  } else {
    data::ImageWriteOptions wo;
    wo.transfer = data::Transfer::Linear;  // the paper's LDR codes, as the estimator reads them back
    data::write_image(out, data::to_ldr(image, exposure), wo);
  }
  write_file_atomic(intr_path, intr.dump(2) + "\n");
  if (a.has("--json")) std::printf("%s\n", result.dump().c_str());
  std::fprintf(stderr, "crop: %s -> %s (%dx%d, fov %.1f, yaw %.1f, pitch %.1f)\n", pano_path.c_str(), out.c_str(), width,
               height, fov, yaw, pitch);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
