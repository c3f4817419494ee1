#include "data/image_io.h"

#include <unistd.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <utility>
#include <vector>

#include "data/exr_header.h"
#include "util/parallel.h"
#include "util/file.h"

namespace sl::data {

namespace fs = std::filesystem;

float srgb_to_linear(float c) {
  if (!(c > 0.0f)) return 0.0f;
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float l) {
  if (!(l > 0.0f)) return 0.0f;
  return l <= 0.0031308f ? 12.92f * l : 1.055f * std::pow(l, 1.0f / 2.4f) - 0.055f;
}

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool is_float_type(OIIO::TypeDesc t) {
  return t.basetype == OIIO::TypeDesc::FLOAT || t.basetype == OIIO::TypeDesc::HALF ||
         t.basetype == OIIO::TypeDesc::DOUBLE;
}

// Colour channels get the transfer curve; alpha (the 2nd of 2 or the 4th of 4) never does.
bool is_alpha(int channel, int channels) {
  return (channels == 2 && channel == 1) || (channels == 4 && channel == 3);
}

// An open ImageInput with its spec; every failure names the file.
struct OpenedInput {
  std::unique_ptr<OIIO::ImageInput> in;
  OIIO::ImageSpec spec;
};

OpenedInput open_input(const std::string& path, const char* op) {
  SL_CHECK(!path.empty(), op, ": empty file name");
  std::error_code ec;
  SL_CHECK(fs::exists(path, ec), op, ": '", path, "': no such file");
  SL_CHECK(!fs::is_directory(path, ec), op, ": '", path, "' is a directory, not an image");
  // OpenEXR allocates what its header declares while opening, so the header is checked first.
  const ExrHeaderSummary exr = summarize_exr_header(path);
  SL_CHECK(exr.attribute_past_end.empty(), op, ": '", path, "': header attribute '", exr.attribute_past_end,
           "' declares ", exr.attribute_bytes, " bytes, past the end of the file (truncated or corrupt)");
  SL_CHECK(exr.largest_window_pixels <= kMaxImageValues, op, ": '", path, "' declares a data window of ",
           exr.largest_window_pixels, " pixels, above the limit of ", kMaxImageValues,
           " values (corrupt or hostile header?)");
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  OpenedInput r;
  r.in = OIIO::ImageInput::open(path, &config);
  if (!r.in) fail(op, ": '", path, "': cannot open as an image: ", OIIO::geterror());
  r.spec = r.in->spec();
  SL_CHECK(r.spec.width > 0 && r.spec.height > 0 && r.spec.nchannels > 0, op, ": '", path,
           "': invalid image size ", r.spec.width, "x", r.spec.height, "x", r.spec.nchannels);
  SL_CHECK(r.spec.depth <= 1, op, ": '", path, "': volume images are not supported");
  return r;
}

// Collects what is written to file descriptor 2 while alive. libpng's default error handler
// prints "libpng error: ..." straight to stderr, and OpenImageIO prints any error still
// pending when a reader is destroyed; a damaged file must give the caller ONE line, so the
// reader's output is collected and handed back (put into the error, or passed on when the
// read succeeds). The descriptor is process-wide, so the capture is too: reads that overlap in
// time (threads of a loader) share one redirection, made by the first and undone by the last,
// which alone hands back what was collected. Each redirecting and restoring on its own would
// leave descriptor 2 pointing at a deleted temporary file once two reads overlap.
class StderrCapture {
 public:
  StderrCapture() {
    std::lock_guard<std::mutex> lock(mutex());
    State& s = state();
    if (s.users++ == 0) {
      std::fflush(stderr);
      s.file = std::tmpfile();
      s.saved = s.file ? ::dup(STDERR_FILENO) : -1;
      if (s.saved >= 0) ::dup2(::fileno(s.file), STDERR_FILENO);
    }
    active_ = true;
  }
  ~StderrCapture() { finish(); }
  // What was written while this capture and any overlapping ones were alive; "" for every
  // capture but the last of an overlapping group (its text goes to that last one).
  std::string finish() {
    std::string text;
    if (!active_) return text;
    active_ = false;
    std::lock_guard<std::mutex> lock(mutex());
    State& s = state();
    if (--s.users > 0) return text;
    if (s.saved >= 0) {
      std::fflush(stderr);
      ::dup2(s.saved, STDERR_FILENO);
      ::close(s.saved);
    }
    if (s.file) {
      std::rewind(s.file);
      char buf[1024];
      size_t got;
      while ((got = std::fread(buf, 1, sizeof buf, s.file)) > 0) text.append(buf, got);
      std::fclose(s.file);
    }
    s = State{};
    return text;
  }

 private:
  struct State {
    std::FILE* file = nullptr;
    int saved = -1;
    int users = 0;
  };
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static State& state() {
    static State s;
    return s;
  }
  bool active_ = false;
};

std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

// Reads all channels interleaved as `type`; fails with the reader's message on damaged data,
// as one line (every message of the reader and of libpng is collected into it).
template <class T>
std::vector<T> read_pixels(OpenedInput& f, OIIO::TypeDesc type, const std::string& path,
                           const char* op) {
  const size_t n = static_cast<size_t>(f.spec.width) * f.spec.height * f.spec.nchannels;
  SL_CHECK(n <= static_cast<size_t>(kMaxImageValues), op, ": '", path, "' declares ", f.spec.width, "x",
           f.spec.height, "x", f.spec.nchannels, " values, above the limit of ", kMaxImageValues,
           " (corrupt or hostile header?)");
  std::vector<T> buf(n);
  StderrCapture capture;
  const bool ok = f.in->read_image(0, 0, 0, f.spec.nchannels, type, buf.data());
  std::string message = f.in->geterror();
  const bool closed = f.in->close();
  const std::string on_close = f.in->geterror();  // retrieved, so nothing is left to print later
  if (message.empty()) message = on_close;
  const bool good = ok && closed && message.empty();
  if (!good) f.in.reset();  // destroyed while collected
  const std::string printed = capture.finish();
  if (good) {
    if (!printed.empty()) std::fputs(printed.c_str(), stderr);
    return buf;
  }
  fail(op, ": '", path, "': truncated or corrupt image data: ", one_line(message.empty() ? "read failed" : message));
}

void check_size(const OIIO::ImageSpec& spec, int width, int height, const std::string& path,
                const char* op) {
  SL_CHECK((width <= 0 || spec.width == width) && (height <= 0 || spec.height == height), op,
           ": '", path, "' is ", spec.width, "x", spec.height, ", expected ",
           width > 0 ? std::to_string(width) : std::string("any"), "x",
           height > 0 ? std::to_string(height) : std::string("any"));
}

// Writes interleaved pixels of `type` through a temporary file and renames it into place.
void write_pixels(const std::string& path, const OIIO::ImageSpec& spec_in, const void* pixels,
                  const char* op) {
  // OIIO stamps EXR files with the current time (capDate) unless told otherwise; an empty
  // DateTime keeps files a pure function of their pixels, so a seed reproduces them byte for byte.
  OIIO::ImageSpec spec = spec_in;
  spec.attribute("DateTime", "");
  const fs::path parent = fs::path(path).parent_path();
  std::error_code ec;
  SL_CHECK(parent.empty() || fs::is_directory(parent, ec), op, ": '", path,
           "': folder does not exist");
  auto out = OIIO::ImageOutput::create(path);
  if (!out) fail(op, ": '", path, "': no writer for this extension: ", OIIO::geterror());
  const std::string tmp = temp_sibling(path, /*keep_extension=*/true);  // OIIO picks the writer by extension
  bool ok = out->open(tmp, spec);
  ok = ok && out->write_image(spec.format, pixels);
  ok = out->close() && ok;
  if (!ok) {
    const std::string message = out->geterror();
    fs::remove(tmp, ec);
    fail(op, ": '", path, "': write failed: ", message);
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    fail(op, ": '", path, "': cannot rename the temporary file into place: ", ec.message());
  }
}

// [C, H, W] float or double tensor → contiguous F32 copy of its values.
std::vector<float> planar_values(const Tensor& t, const std::string& path, const char* op) {
  SL_CHECK(t.defined(), op, ": '", path, "': tensor is undefined");
  SL_CHECK(t.dtype() == DType::F32 || t.dtype() == DType::F64, op, ": '", path,
           "': expected an F32 or F64 tensor, got ", t.describe());
  const std::vector<double> v = t.detach().to_vector();
  return std::vector<float>(v.begin(), v.end());
}

int orientation_of(const OIIO::ImageSpec& spec) {
  const int o = spec.get_int_attribute("Orientation", 1);
  return o >= 1 && o <= 8 ? o : 1;
}

// The stored (row, column) shown at upright (r, c) for EXIF orientation o, stored size h x w.
// The tag says where the 0th stored row and column appear: 2 mirrors, 3 turns 180 degrees, 4 flips,
// 5 transposes, 6 turns a quarter clockwise, 7 transposes across the other diagonal, 8 turns a
// quarter counter-clockwise.
inline std::pair<int64_t, int64_t> stored_pixel(int o, int64_t r, int64_t c, int64_t h, int64_t w) {
  switch (o) {
    case 2: return {r, w - 1 - c};
    case 3: return {h - 1 - r, w - 1 - c};
    case 4: return {h - 1 - r, c};
    case 5: return {c, r};
    case 6: return {h - 1 - c, r};
    case 7: return {h - 1 - c, w - 1 - r};
    case 8: return {c, w - 1 - r};
    default: return {r, c};
  }
}

}  // namespace

ImageInfo read_image_info(const std::string& path) {
  OpenedInput f = open_input(path, "read_image_info");
  ImageInfo info;
  info.width = f.spec.width;
  info.height = f.spec.height;
  info.channels = f.spec.nchannels;
  info.is_float = is_float_type(f.spec.format);
  info.bits = static_cast<int>(f.spec.format.size() * 8);
  info.orientation = orientation_of(f.spec);
  const int focal = f.spec.get_int_attribute("Exif:FocalLengthIn35mmFilm", 0);
  info.focal_35mm = focal > 0 ? focal : 0.0;
  return info;
}

Tensor read_image(const std::string& path, const ImageReadOptions& options) {
  const char* op = "read_image";
  OpenedInput f = open_input(path, op);
  const int fc = f.spec.nchannels, w = f.spec.width, h = f.spec.height;
  const int orientation = options.upright ? orientation_of(f.spec) : 1;
  const bool swap = orientation_swaps_axes(orientation);
  const int out_w = swap ? h : w, out_h = swap ? w : h;
  SL_CHECK((options.width <= 0 || out_w == options.width) && (options.height <= 0 || out_h == options.height), op,
           ": '", path, "' is ", out_w, "x", out_h, swap ? " upright" : "", ", expected ",
           options.width > 0 ? std::to_string(options.width) : std::string("any"), "x",
           options.height > 0 ? std::to_string(options.height) : std::string("any"));
  const int want = options.channels == 0 ? fc : options.channels;
  SL_CHECK(want == 1 || want == 2 || want == 3 || want == 4, op, ": '", path,
           "': requested channel count must be 0-4, got ", options.channels);
  const bool grey_to_rgb = want == 3 && fc == 1;
  const bool drop_alpha = want == 3 && fc == 4;
  SL_CHECK(want == fc || grey_to_rgb || drop_alpha, op, ": '", path, "' has ", fc,
           " channels, expected ", want);
  const bool float_file = is_float_type(f.spec.format);
  const std::vector<float> buf = read_pixels<float>(f, OIIO::TypeDesc::FLOAT, path, op);

  const bool curve = options.transfer == Transfer::SRGB ||
                     (options.transfer == Transfer::Auto && !float_file);
  Tensor image = Tensor::empty({want, out_h, out_w}, DType::F32);
  float* dst = image.data<float>();
  const int64_t plane = static_cast<int64_t>(w) * h;
  parallel_for(plane, 16384, [&](int64_t p0, int64_t p1) {
    for (int c = 0; c < want; ++c) {
      const int src_c = grey_to_rgb ? 0 : c;
      const bool apply = curve && !is_alpha(c, want);
      for (int64_t p = p0; p < p1; ++p) {
        int64_t q = p;  // the stored pixel shown at upright pixel p
        if (orientation != 1) {
          const auto [sr, sc] = stored_pixel(orientation, p / out_w, p % out_w, h, w);
          q = sr * w + sc;
        }
        const float x = buf[static_cast<size_t>(q * fc + src_c)];
        dst[c * plane + p] = apply ? srgb_to_linear(x) : x;
      }
    }
  });
  return image;
}

void write_image(const std::string& path, const Tensor& image, const ImageWriteOptions& options) {
  const char* op = "write_image";
  SL_CHECK(image.defined() && image.dim() == 3, op, ": '", path,
           "': expected a [C, H, W] tensor, got ", image.defined() ? image.describe() : "undefined");
  const int c = static_cast<int>(image.size(0)), h = static_cast<int>(image.size(1)),
            w = static_cast<int>(image.size(2));
  SL_CHECK(c >= 1 && c <= 4 && h > 0 && w > 0, op, ": '", path,
           "': expected 1-4 channels and a non-empty image, got ", image.describe());
  const std::string ext = lower_extension(path);
  const bool is_exr = ext == ".exr", is_hdr = ext == ".hdr", is_png = ext == ".png",
             is_jpg = ext == ".jpg" || ext == ".jpeg";
  SL_CHECK(is_exr || is_hdr || is_png || is_jpg, op, ": '", path, "': unsupported extension '",
           ext, "' (use .exr, .hdr, .png, .jpg)");
  SL_CHECK(!is_hdr || c == 3, op, ": '", path, "': Radiance .hdr needs 3 channels, got ", c);
  SL_CHECK(!is_jpg || c == 1 || c == 3, op, ": '", path, "': JPEG needs 1 or 3 channels, got ", c);
  const bool float_file = is_exr || is_hdr;
  const int bits = float_file ? 32 : options.bits;
  SL_CHECK(float_file || bits == 8 || (bits == 16 && is_png), op, ": '", path,
           "': unsupported bit depth ", options.bits, " for ", ext);

  const std::vector<float> planar = planar_values(image, path, op);
  const bool curve = options.transfer == Transfer::SRGB ||
                     (options.transfer == Transfer::Auto && !float_file);
  const int64_t plane = static_cast<int64_t>(w) * h;
  const double max_code = bits == 16 ? 65535.0 : 255.0;
  std::vector<float> f32(float_file ? planar.size() : 0);
  std::vector<uint8_t> u8(bits == 8 ? planar.size() : 0);
  std::vector<uint16_t> u16(bits == 16 ? planar.size() : 0);
  parallel_for(plane, 16384, [&](int64_t p0, int64_t p1) {
    for (int ch = 0; ch < c; ++ch) {
      const bool apply = curve && !is_alpha(ch, c);
      for (int64_t p = p0; p < p1; ++p) {
        float x = planar[static_cast<size_t>(ch * plane + p)];
        if (std::isnan(x)) x = 0.0f;
        if (apply) x = linear_to_srgb(x);
        const size_t i = static_cast<size_t>(p * c + ch);
        if (float_file) {
          f32[i] = x;
        } else {
          const double code = std::nearbyint(std::clamp(static_cast<double>(x), 0.0, 1.0) * max_code);
          if (bits == 8) u8[i] = static_cast<uint8_t>(code);
          else u16[i] = static_cast<uint16_t>(code);
        }
      }
    }
  });
  const OIIO::TypeDesc type = float_file ? OIIO::TypeDesc::FLOAT
                              : bits == 8 ? OIIO::TypeDesc::UINT8
                                          : OIIO::TypeDesc::UINT16;
  OIIO::ImageSpec spec(w, h, c, type);
  if (c == 4) spec.alpha_channel = 3;
  if (c == 4 && is_png) spec.attribute("oiio:UnassociatedAlpha", 1);
  const void* pixels = float_file ? static_cast<const void*>(f32.data())
                       : bits == 8 ? static_cast<const void*>(u8.data())
                                   : static_cast<const void*>(u16.data());
  write_pixels(path, spec, pixels, op);
}

Tensor read_depth(const std::string& path, MissingDepth missing, int width, int height) {
  const char* op = "read_depth";
  OpenedInput f = open_input(path, op);
  check_size(f.spec, width, height, path, op);
  SL_CHECK(f.spec.nchannels == 1, op, ": '", path, "' has ", f.spec.nchannels,
           " channels, expected 1 (a depth map)");
  const int w = f.spec.width, h = f.spec.height;
  const float hole = missing == MissingDepth::Zero ? 0.0f : std::nanf("");
  const size_t n = static_cast<size_t>(w) * h;
  // The tensor is allocated only after read_pixels has checked the declared size against
  // kMaxImageValues (a 398-byte EXR header declared 3.6e9 pixels: 14 GB before the check).
  Tensor depth;
  if (is_float_type(f.spec.format)) {
    const std::vector<float> buf = read_pixels<float>(f, OIIO::TypeDesc::FLOAT, path, op);
    depth = Tensor::empty({1, h, w}, DType::F32);
    float* dst = depth.data<float>();
    for (size_t i = 0; i < n; ++i)
      dst[i] = std::isfinite(buf[i]) && buf[i] > 0.0f ? buf[i] : hole;
  } else {
    SL_CHECK(f.spec.format == OIIO::TypeDesc::UINT16, op, ": '", path,
             "': an integer depth map must be 16-bit (KITTI: metres = value / 256), got ",
             f.spec.format.size() * 8, "-bit");
    const std::vector<uint16_t> buf = read_pixels<uint16_t>(f, OIIO::TypeDesc::UINT16, path, op);
    depth = Tensor::empty({1, h, w}, DType::F32);
    float* dst = depth.data<float>();
    for (size_t i = 0; i < n; ++i) dst[i] = buf[i] == 0 ? hole : static_cast<float>(buf[i]) / 256.0f;
  }
  return depth;
}

void write_depth(const std::string& path, const Tensor& depth_m) {
  const char* op = "write_depth";
  SL_CHECK(depth_m.defined() && (depth_m.dim() == 2 || (depth_m.dim() == 3 && depth_m.size(0) == 1)),
           op, ": '", path, "': expected a [1, H, W] or [H, W] tensor, got ",
           depth_m.defined() ? depth_m.describe() : "undefined");
  const int h = static_cast<int>(depth_m.size(-2)), w = static_cast<int>(depth_m.size(-1));
  SL_CHECK(h > 0 && w > 0, op, ": '", path, "': empty depth map ", depth_m.describe());
  const std::string ext = lower_extension(path);
  SL_CHECK(ext == ".exr" || ext == ".png", op, ": '", path, "': unsupported extension '", ext,
           "' for a depth map (use .exr or 16-bit KITTI .png)");
  const std::vector<float> d = planar_values(depth_m, path, op);
  if (ext == ".exr") {
    std::vector<float> out(d.size());
    for (size_t i = 0; i < d.size(); ++i)
      out[i] = std::isfinite(d[i]) && d[i] > 0.0f ? d[i] : std::nanf("");
    write_pixels(path, OIIO::ImageSpec(w, h, 1, OIIO::TypeDesc::FLOAT), out.data(), op);
    return;
  }
  std::vector<uint16_t> out(d.size());
  for (size_t i = 0; i < d.size(); ++i) {
    if (!(std::isfinite(d[i]) && d[i] > 0.0f)) {
      out[i] = 0;
      continue;
    }
    const double code = std::nearbyint(static_cast<double>(d[i]) * 256.0);
    SL_CHECK(code <= 65535.0, op, ": '", path, "': depth ", d[i], " m at pixel (",
             i % static_cast<size_t>(w), ", ", i / static_cast<size_t>(w),
             ") exceeds the 16-bit PNG range (max 255.996 m); use .exr");
    out[i] = static_cast<uint16_t>(std::max(1.0, code));  // a tiny positive depth is not a hole
  }
  write_pixels(path, OIIO::ImageSpec(w, h, 1, OIIO::TypeDesc::UINT16), out.data(), op);
}

}  // namespace sl::data
