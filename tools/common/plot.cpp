#include "tools/common/plot.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <glm/glm.hpp>

namespace sl::cli {
namespace {

struct Canvas {
  int w, h;
  std::vector<glm::vec3> px;
  Canvas(int width, int height) : w(width), h(height), px(size_t(width) * height, glm::vec3(1.0f)) {}
  void dot(int x, int y, const glm::vec3& c, int radius = 1) {
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx)
        if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h) px[size_t(y + dy) * w + x + dx] = c;
  }
  void line(double x0, double y0, double x1, double y1, const glm::vec3& c, int radius = 1) {
    const int n = std::max(1, int(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))));
    for (int i = 0; i <= n; ++i) {
      const double t = double(i) / n;
      dot(int(std::lround(x0 + t * (x1 - x0))), int(std::lround(y0 + t * (y1 - y0))), c, radius);
    }
  }
  // A 3×5 bitmap font (digits, upper-case letters, a few signs; lower case is drawn upper case),
  // scaled ×2. Returns the x after the text.
  int text(int x, int y, const std::string& s, const glm::vec3& c) {
    static const std::map<char, const char*> glyphs = {
        {'0', "111101101101111"}, {'1', "010110010010111"}, {'2', "111001111100111"}, {'3', "111001111001111"},
        {'4', "101101111001001"}, {'5', "111100111001111"}, {'6', "111100111101111"}, {'7', "111001001001001"},
        {'8', "111101111101111"}, {'9', "111101111001111"}, {'.', "000000000000010"}, {'-', "000000111000000"},
        {'A', "010101111101101"}, {'B', "110101110101110"}, {'C', "011100100100011"},
        {'D', "110101101101110"}, {'E', "111100110100111"}, {'F', "111100110100100"}, {'G', "011100101101011"},
        {'H', "101101111101101"}, {'I', "111010010010111"}, {'J', "001001001101010"}, {'K', "101101110101101"},
        {'L', "100100100100111"}, {'M', "101111111101101"}, {'N', "110101101101101"}, {'O', "010101101101010"},
        {'P', "110101110100100"}, {'Q', "010101101110011"}, {'R', "110101110101101"}, {'S', "011100010001110"},
        {'T', "111010010010010"}, {'U', "101101101101111"}, {'V', "101101101101010"}, {'W', "101101111111101"},
        {'X', "101101010101101"}, {'Y', "101101010010010"}, {'Z', "111001010100111"}, {'_', "000000000000111"},
        {'/', "001001010100100"}, {'(', "010100100100010"}, {')', "010001001001010"}, {':', "000010000010000"}};
    for (char ch : s) {
      auto it = glyphs.find(ch);
      if (it == glyphs.end() && ch >= 'a' && ch <= 'z') it = glyphs.find(char(ch - 'a' + 'A'));
      if (it != glyphs.end())
        for (int r = 0; r < 5; ++r)
          for (int k = 0; k < 3; ++k)
            if (it->second[r * 3 + k] == '1')
              for (int sy = 0; sy < 2; ++sy)
                for (int sx = 0; sx < 2; ++sx) dot(x + 2 * k + sx, y + 2 * r + sy, c, 0);
      x += 8;
    }
    return x;
  }
  Tensor tensor() const {
    Tensor t = Tensor::empty({3, h, w});
    float* p = t.data<float>();
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < px.size(); ++i) p[c * px.size() + i] = px[i][c];
    return t;
  }
};

}  // namespace

std::vector<float> series_colour(size_t k) {
  static const float palette[][3] = {{0.1f, 0.3f, 0.9f}, {0.9f, 0.15f, 0.1f}, {0.1f, 0.6f, 0.2f},
                                     {0.6f, 0.2f, 0.7f}, {0.95f, 0.55f, 0.0f}, {0.3f, 0.3f, 0.3f}};
  const float* c = palette[k % 6];
  return {c[0], c[1], c[2]};
}

Tensor error_time_plot(const std::vector<PlotPoint>& pts, int width, int height) {
  Canvas cv(width, height);
  const int left = 70, right = width - 20, top = 20, bottom = height - 50;
  double tx0 = 1e300, tx1 = -1e300, ey0 = 1e300, ey1 = -1e300;
  for (const PlotPoint& p : pts) {
    tx0 = std::min(tx0, std::log10(p.time_ms));
    tx1 = std::max(tx1, std::log10(p.time_ms));
    ey0 = std::min(ey0, std::log10(std::max(p.error, 1e-12)));
    ey1 = std::max(ey1, std::log10(std::max(p.error, 1e-12)));
  }
  tx0 = std::floor(tx0), tx1 = std::ceil(tx1 + 1e-9), ey0 = std::floor(ey0), ey1 = std::ceil(ey1 + 1e-9);
  auto X = [&](double t) { return left + (std::log10(t) - tx0) / (tx1 - tx0) * (right - left); };
  auto Y = [&](double e) { return bottom - (std::log10(std::max(e, 1e-12)) - ey0) / (ey1 - ey0) * (bottom - top); };
  const glm::vec3 grey(0.8f), black(0.0f);
  for (int k = int(tx0); k <= int(tx1); ++k) {  // decade grid and labels (time in ms)
    const double x = X(std::pow(10.0, k));
    cv.line(x, top, x, bottom, grey, 0);
    cv.text(int(x) - 12, bottom + 10, "1e" + std::to_string(k), black);
  }
  for (int k = int(ey0); k <= int(ey1); ++k) {
    const double y = Y(std::pow(10.0, k));
    cv.line(left, y, right, y, grey, 0);
    cv.text(8, int(y) - 5, "1e" + std::to_string(k), black);
  }
  cv.text((left + right) / 2 - 40, bottom + 30, "time (ms)", black);
  cv.text(left + 6, top - 14 < 0 ? 2 : top - 14, "error", black);
  cv.line(left, bottom, right, bottom, black);
  cv.line(left, top, left, bottom, black);
  std::vector<std::string> series;
  for (const PlotPoint& p : pts)
    if (std::find(series.begin(), series.end(), p.series) == series.end()) series.push_back(p.series);
  for (size_t k = 0; k < series.size(); ++k) {
    const auto rgb = series_colour(k);
    const glm::vec3 c(rgb[0], rgb[1], rgb[2]);
    const PlotPoint* prev = nullptr;
    for (const PlotPoint& p : pts) {
      if (p.series != series[k]) continue;
      if (prev) cv.line(X(prev->time_ms), Y(prev->error), X(p.time_ms), Y(p.error), c);
      cv.dot(int(X(p.time_ms)), int(Y(p.error)), c, 3);
      prev = &p;
    }
    // Legend: a swatch and the series name, top right.
    const int ly = top + 8 + 16 * int(k), lx = right - 12 - 8 * int(series[k].size()) - 28;
    cv.line(lx, ly + 4, lx + 20, ly + 4, c, 1);
    cv.text(lx + 26, ly, series[k], glm::vec3(0.0f));
  }
  return cv.tensor();
}


}  // namespace sl::cli
