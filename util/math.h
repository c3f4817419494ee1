// Small math shared by every layer: π, degree/radian conversion, luminance and the LDR gamma.
//
// Contract: header-only, constexpr where the standard library allows, no state. The LDR gamma
// is the paper's (Sec 3.4): LDR = clip((exposure·L)^(1/2.2), 0, 1), so decoding an 8-bit photo
// to exposure-normalised radiance is LDR^2.2.
#pragma once
#include <algorithm>
#include <cmath>

#include <glm/vec3.hpp>

namespace sl {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTwoPi = 2.0 * kPi;
inline constexpr float kPiF = static_cast<float>(kPi);

inline constexpr double kDegToRad = kPi / 180.0;
constexpr double radians(double deg) { return deg * kDegToRad; }
constexpr double degrees(double rad) { return rad / kDegToRad; }

// Rec. 709 / sRGB luminance of linear RGB.
inline constexpr double kLumR = 0.2126, kLumG = 0.7152, kLumB = 0.0722;
constexpr double luminance(double r, double g, double b) { return kLumR * r + kLumG * g + kLumB * b; }
inline float luminance(const glm::vec3& c) {
  return static_cast<float>(kLumR) * c.r + static_cast<float>(kLumG) * c.g + static_cast<float>(kLumB) * c.b;
}

// The LDR gamma of Sec 3.4.
inline constexpr double kLdrGamma = 2.2;
// clip((exposure·x)^(1/2.2), 0, 1) for one linear value.
inline double ldr_encode(double x, double exposure = 1.0) {
  return std::clamp(std::pow(std::max(exposure * x, 0.0), 1.0 / kLdrGamma), 0.0, 1.0);
}
// An LDR value back to exposure-normalised linear radiance: v^2.2.
inline double ldr_decode(double v) { return std::pow(v, kLdrGamma); }

// The exposure that maps a median luminance to the LDR value `ldr_median` under the LDR above:
// ldr_median^2.2 / median; 1 when the median is (nearly) zero. render/exposure.h applies it
// to images.
inline double exposure_for_median(double median_luminance, double ldr_median) {
  return median_luminance > 1e-12 ? ldr_decode(ldr_median) / median_luminance : 1.0;
}

}  // namespace sl
