// The paper's evaluation metrics (Sec 4.2), on plain data (no tape).
//
// - angular_error_deg: angle between two directions in degrees (0 for a zero vector: reported
//   as 180, the worst case, so a degenerate prediction is never rewarded).
// - median / mean of a list (0 for an empty list).
// - psnr(pred, target): 10·log10(1 / MSE) for images in [0, 1]; MSE floored at 1e-10.
// - si_psnr(pred, target): PSNR after scaling pred by the least-squares factor
//   s = <p, t> / <p, p> ("we multiply the predicted novel view with a scaling factor that
//   minimizes L2 error"); s = 1 when p = 0.
// - masked_psnr(pred, target, mask): both over the pixels whose mask entry is non-zero, for
//   images [C, H, W] and a mask of H·W entries (empty: every pixel); valid = false when no pixel
//   is selected. psnr() and si_psnr() are masked_psnr() over every element.
#pragma once
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"

namespace sl::train {

double angular_error_deg(const glm::dvec3& a, const glm::dvec3& b);
double median(std::vector<double> values);
double mean_of(const std::vector<double>& values);
struct PsnrScores {
  double psnr = 0.0, si_psnr = 0.0;
  bool valid = false;
};
PsnrScores masked_psnr(const Tensor& pred, const Tensor& target, const std::vector<char>& mask);
double psnr(const Tensor& pred, const Tensor& target);
double si_psnr(const Tensor& pred, const Tensor& target);

}  // namespace sl::train
