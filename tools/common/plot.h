// Error-against-time plots for benchmarks and evaluation: a log-log line chart drawn into an RGB
// image tensor (no plotting library), one coloured line per series in order of first
// appearance, with decade grid lines and "1eK" tick labels (x: time in ms, y: error).
// Contract: points with non-positive time or error are clamped to 1e-12; the image is
// [3, height, width] F32 in [0, 1] (write it with data/image_io.h).
#pragma once
#include <string>
#include <vector>

#include "autodiff/tensor.h"

namespace sl::cli {

struct PlotPoint {
  std::string series;
  double time_ms;
  double error;
};

Tensor error_time_plot(const std::vector<PlotPoint>& points, int width = 640, int height = 420);

// The colour of the k-th series (also for legends drawn elsewhere), RGB in [0, 1].
std::vector<float> series_colour(size_t k);

}  // namespace sl::cli
