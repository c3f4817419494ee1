#include "data/contact_sheet.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "data/image_io.h"
#include "util/error.h"

namespace sl::data {

namespace fs = std::filesystem;

namespace {

// Nearest-neighbour resize of a [C, H, W] image to height `th`, as RGB.
Tensor to_tile(const Tensor& img, int th) {
  const int C = static_cast<int>(img.size(0)), H = static_cast<int>(img.size(1)), W = static_cast<int>(img.size(2));
  const int tw = std::max(1, static_cast<int>(std::lround(static_cast<double>(W) * th / H)));
  Tensor out = Tensor::zeros({3, th, tw});
  const float* s = img.data<float>();
  float* d = out.data<float>();
  for (int y = 0; y < th; ++y)
    for (int x = 0; x < tw; ++x) {
      const int sy = std::min(H - 1, y * H / th), sx = std::min(W - 1, x * W / tw);
      for (int c = 0; c < 3; ++c)
        d[(static_cast<size_t>(c) * th + y) * tw + x] = s[(static_cast<size_t>(std::min(c, C - 1)) * H + sy) * W + sx];
    }
  return out;
}

Tensor read_ldr(const fs::path& p) {
  ImageReadOptions o;
  o.transfer = Transfer::Linear;
  o.channels = 3;
  return read_image(p.string(), o).contiguous();
}

// Inverse depth, normalised so the nearest 2 % of pixels are white; missing depth is black.
Tensor depth_tile(const fs::path& p) {
  Tensor d = read_depth(p.string()).contiguous();
  float* v = d.data<float>();
  std::vector<float> inv;
  for (int64_t i = 0; i < d.numel(); ++i)
    if (v[i] > 0.0f) inv.push_back(1.0f / v[i]);
  float hi = 1.0f;
  if (!inv.empty()) {
    std::nth_element(inv.begin(), inv.begin() + inv.size() * 98 / 100, inv.end());
    hi = std::max(1e-6f, inv[inv.size() * 98 / 100]);
  }
  for (int64_t i = 0; i < d.numel(); ++i) v[i] = v[i] > 0.0f ? std::min(1.0f, std::sqrt((1.0f / v[i]) / hi)) : 0.0f;
  return d;
}

}  // namespace

Tensor compose_contact_sheet(const std::string& dataset_dir, int rows, int th) {
  SL_CHECK(rows >= 1 && th >= 8, "compose_contact_sheet: rows >= 1 and tile_height >= 8 required, got ", rows, ", ",
           th);
  const fs::path samples = fs::path(dataset_dir) / "samples";
  std::vector<fs::path> dirs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(samples, ec))
    if (e.is_directory() && e.path().extension() != ".tmp") dirs.push_back(e.path());
  SL_CHECK(!ec && !dirs.empty(), "compose_contact_sheet: no samples in '", samples.string(), "'");
  std::sort(dirs.begin(), dirs.end());
  dirs.resize(std::min<size_t>(dirs.size(), rows));

  const int gap = 4;
  std::vector<std::vector<Tensor>> grid;
  for (const fs::path& d : dirs) {
    std::vector<Tensor> row{to_tile(read_ldr(d / "pano_ldr.png"), th)};
    for (int v = 0; fs::exists(d / ("view_" + std::to_string(v) + "_ldr.png")); ++v) {
      row.push_back(to_tile(read_ldr(d / ("view_" + std::to_string(v) + "_ldr.png")), th));
      row.push_back(to_tile(depth_tile(d / ("view_" + std::to_string(v) + "_depth.exr")), th));
    }
    if (fs::exists(d / "insert_with_object_ldr.png")) {
      row.push_back(to_tile(read_ldr(d / "view_0_ldr.png"), th));
      row.push_back(to_tile(read_ldr(d / "insert_with_object_ldr.png"), th));
    }
    grid.push_back(std::move(row));
  }
  int width = 0;
  for (const auto& row : grid) {
    int w = 0;
    for (const Tensor& t : row) w += static_cast<int>(t.size(2)) + gap;
    width = std::max(width, w + gap);
  }
  const int height = static_cast<int>(grid.size()) * (th + gap) + gap;
  Tensor sheet = Tensor::full({3, height, width}, 1.0);
  float* s = sheet.data<float>();
  for (size_t r = 0; r < grid.size(); ++r) {
    int x0 = gap;
    const int y0 = gap + static_cast<int>(r) * (th + gap);
    for (const Tensor& t : grid[r]) {
      const int tw = static_cast<int>(t.size(2));
      const float* p = t.data<float>();
      for (int c = 0; c < 3; ++c)
        for (int y = 0; y < th; ++y)
          for (int x = 0; x < tw; ++x)
            s[(static_cast<size_t>(c) * height + y0 + y) * width + x0 + x] = p[(static_cast<size_t>(c) * th + y) * tw + x];
      x0 += tw + gap;
    }
  }
  return sheet;
}

void write_contact_sheet(const std::string& dataset_dir, const std::string& png_path, int rows, int th) {
  ImageWriteOptions o;
  o.transfer = Transfer::Linear;  // tiles hold display values already
  write_image(png_path, compose_contact_sheet(dataset_dir, rows, th), o);
}

}  // namespace sl::data
