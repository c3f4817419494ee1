#include "data/sky_model.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/equirect.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::data {

namespace {

constexpr double kSunAngularRadiusRad = 0.265 * kPi / 180.0;
// Solar disk luminance before atmospheric attenuation, in kcd/m². The extraterrestrial value
// (~128 klx over the disk's solid angle) is 1.9e6, which puts a clear-sky sun at up to 1.4e5
// times the mean sky radiance; the project specifies 10^4-10^5 times the sky's, so the disk is
// scaled to 1.3e6: 1.4e4 (elevation 5°) to 9.6e4 (75°) times the mean upper-hemisphere sky at
// turbidity 3 (tests/data/sky_model_test.cpp). Below ~5° air mass dims it further, as it should.
constexpr double kSunLuminanceOutsideAtmosphere = 1.3e6;
constexpr int kSunSamples = 256;

// Perez et al. coefficients A..E as linear functions of turbidity T (Preetham 1999, Appendix).
void perez_coefficients(double t, const double (&m)[5][2], double (&out)[5]) {
  for (int i = 0; i < 5; ++i) out[i] = m[i][0] * t + m[i][1];
}
constexpr double kPerezY[5][2] = {{0.1787, -1.4630}, {-0.3554, 0.4275}, {-0.0227, 5.3251},
                                  {0.1206, -2.5771}, {-0.0670, 0.3703}};
constexpr double kPerezX[5][2] = {{-0.0193, -0.2592}, {-0.0665, 0.0008}, {-0.0004, 0.2125},
                                  {-0.0641, -0.8989}, {-0.0033, 0.0452}};
constexpr double kPerezYc[5][2] = {{-0.0167, -0.2608}, {-0.0950, 0.0092}, {-0.0079, 0.2102},
                                   {-0.0441, -1.6537}, {-0.0109, 0.0529}};

double perez(const double (&c)[5], double cos_theta, double gamma) {
  const double cos_gamma = std::cos(gamma);
  // cos θ is kept ≥ 0.01 so that e^{B/cos θ} stays finite at the horizon (B < 0: it tends to 0).
  return (1.0 + c[0] * std::exp(c[1] / std::max(cos_theta, 0.01))) *
         (1.0 + c[2] * std::exp(c[3] * gamma) + c[4] * cos_gamma * cos_gamma);
}

// Zenith chromaticity: T²·(a·θs³ + ...) + T·(...) + (...) (Preetham 1999, Appendix).
double zenith_chromaticity(const double (&m)[3][4], double t, double theta_s) {
  const double th[4] = {theta_s * theta_s * theta_s, theta_s * theta_s, theta_s, 1.0};
  double rows[3];
  for (int r = 0; r < 3; ++r) rows[r] = m[r][0] * th[0] + m[r][1] * th[1] + m[r][2] * th[2] + m[r][3] * th[3];
  return t * t * rows[0] + t * rows[1] + rows[2];
}
constexpr double kZenithX[3][4] = {{0.00166, -0.00375, 0.00209, 0.0},
                                   {-0.02903, 0.06377, -0.03202, 0.00394},
                                   {0.11693, -0.21196, 0.06052, 0.25886}};
constexpr double kZenithY[3][4] = {{0.00275, -0.00610, 0.00317, 0.0},
                                   {-0.04214, 0.08970, -0.04153, 0.00516},
                                   {0.15346, -0.26756, 0.06670, 0.26688}};

glm::dvec3 xyY_to_linear_srgb(double x, double y, double Y) {
  if (!(y > 1e-9) || !(Y > 0.0)) return glm::dvec3(0.0);
  const double X = x / y * Y, Z = (1.0 - x - y) / y * Y;
  const glm::dvec3 rgb(3.2406 * X - 1.5372 * Y - 0.4986 * Z, -0.9689 * X + 1.8758 * Y + 0.0415 * Z,
                       0.0557 * X - 0.2040 * Y + 1.0570 * Z);
  return glm::max(rgb, glm::dvec3(0.0));
}

double angle_between(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

// Kasten & Young (1989) relative optical air mass for a sun at zenith angle θs.
double air_mass(double theta_s) {
  const double deg = theta_s * 180.0 / kPi;
  return 1.0 / (std::cos(theta_s) + 0.50572 * std::pow(96.07995 - deg, -1.6364));
}

// Value noise in [0, 1] on an integer lattice hashed by seed, smoothly interpolated.
double value_noise(uint64_t seed, double x, double y) {
  const double xf = std::floor(x), yf = std::floor(y);
  const int64_t xi = static_cast<int64_t>(xf), yi = static_cast<int64_t>(yf);
  auto lattice = [&](int64_t i, int64_t j) {
    return uniform01(seed, static_cast<uint64_t>(i) * 0x9E3779B1ULL, static_cast<uint64_t>(j));
  };
  const double sx = x - xf, sy = y - yf;
  const double ux = sx * sx * (3 - 2 * sx), uy = sy * sy * (3 - 2 * sy);
  const double a = lattice(xi, yi), b = lattice(xi + 1, yi), c = lattice(xi, yi + 1),
               d = lattice(xi + 1, yi + 1);
  return (a * (1 - ux) + b * ux) * (1 - uy) + (c * (1 - ux) + d * ux) * uy;
}

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

void check_params(const SkyParams& p) {
  const double half_pi = 0.5 * kPi;
  SL_CHECK(std::isfinite(p.sun_elevation_rad) && p.sun_elevation_rad >= 0.0 &&
               p.sun_elevation_rad <= half_pi + 1e-12,
           "PreethamSky: sun_elevation_rad must be in [0, pi/2], got ", p.sun_elevation_rad);
  SL_CHECK(std::isfinite(p.sun_azimuth_rad), "PreethamSky: sun_azimuth_rad must be finite, got ",
           p.sun_azimuth_rad);
  SL_CHECK(p.turbidity >= 1.7 && p.turbidity <= 10.0,
           "PreethamSky: turbidity must be in [1.7, 10] (the model's fitted range), got ", p.turbidity);
  SL_CHECK(p.ground_albedo >= 0.0 && p.ground_albedo <= 1.0,
           "PreethamSky: ground_albedo must be in [0, 1], got ", p.ground_albedo);
  SL_CHECK(p.cloud_cover >= 0.0 && p.cloud_cover <= 1.0,
           "PreethamSky: cloud_cover must be in [0, 1], got ", p.cloud_cover);
}

}  // namespace

PreethamSky::PreethamSky(const SkyParams& params) : p_(params) {
  check_params(p_);
  const double e = std::min(p_.sun_elevation_rad, 0.5 * kPi);
  sun_dir_ = glm::dvec3(std::cos(e) * std::sin(p_.sun_azimuth_rad), std::sin(e),
                        -std::cos(e) * std::cos(p_.sun_azimuth_rad));
  theta_s_ = 0.5 * kPi - e;
  const double t = p_.turbidity;
  perez_coefficients(t, kPerezY, coef_Y_);
  perez_coefficients(t, kPerezX, coef_x_);
  perez_coefficients(t, kPerezYc, coef_y_);
  // Zenith luminance in kcd/m² (Preetham 1999, Appendix): χ = (4/9 − T/120)(π − 2θs).
  const double chi = (4.0 / 9.0 - t / 120.0) * (kPi - 2.0 * theta_s_);
  zenith_Y_ = std::max(0.0, (4.0453 * t - 4.9710) * std::tan(chi) - 0.2155 * t + 2.4192);
  zenith_x_ = zenith_chromaticity(kZenithX, t, theta_s_);
  zenith_y_ = zenith_chromaticity(kZenithY, t, theta_s_);
  norm_Y_ = perez(coef_Y_, 1.0, theta_s_);
  norm_x_ = perez(coef_x_, 1.0, theta_s_);
  norm_y_ = perez(coef_y_, 1.0, theta_s_);

  // Sun disk radiance: extraterrestrial luminance × Rayleigh and aerosol transmittance.
  const double m = air_mass(theta_s_);
  const double beta = 0.04608 * t - 0.04586;
  const double lambda_um[3] = {0.61, 0.55, 0.465};
  for (int c = 0; c < 3; ++c) {
    const double tau = 0.008735 * std::pow(lambda_um[c], -4.08) + beta * std::pow(lambda_um[c], -1.3);
    sun_rgb_[c] = kSunLuminanceOutsideAtmosphere * std::exp(-m * tau);
  }
  sun_rgb_ *= std::exp(-4.0 * cloud_cover_at(sun_dir_));

  // Ground: albedo · E / π, with E integrated over the upper hemisphere on a midpoint grid.
  const int rows = 48, cols = 96;
  glm::dvec3 irradiance(0.0);
  for (int i = 0; i < rows; ++i) {
    const double el0 = 0.5 * kPi * i / rows, el1 = 0.5 * kPi * (i + 1) / rows;
    const double el = 0.5 * (el0 + el1);
    const double d_omega = (std::sin(el1) - std::sin(el0)) * 2.0 * kPi / cols;
    for (int j = 0; j < cols; ++j) {
      const double az = 2.0 * kPi * (j + 0.5) / cols;
      const glm::dvec3 d(std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az));
      irradiance += radiance(d) * std::sin(el) * d_omega;  // ground_rgb_ is 0 here: y > 0
    }
  }
  if (p_.sun_disk) irradiance += sun_rgb_ * sun_solid_angle() * std::sin(e);
  ground_rgb_ = p_.ground_albedo * irradiance / kPi;
}

double PreethamSky::sun_solid_angle() const {
  return 2.0 * kPi * (1.0 - std::cos(kSunAngularRadiusRad));
}

glm::dvec3 PreethamSky::clear_sky_radiance(const glm::dvec3& direction) const {
  const glm::dvec3 d = glm::normalize(direction);
  const double cos_theta = std::max(0.0, d.y);
  const double gamma = angle_between(d, sun_dir_);
  const double Y = zenith_Y_ * perez(coef_Y_, cos_theta, gamma) / norm_Y_;
  const double x = zenith_x_ * perez(coef_x_, cos_theta, gamma) / norm_x_;
  const double y = zenith_y_ * perez(coef_y_, cos_theta, gamma) / norm_y_;
  return xyY_to_linear_srgb(x, y, Y);
}

double PreethamSky::cloud_cover_at(const glm::dvec3& direction) const {
  if (p_.cloud_cover <= 0.0 || direction.y <= 0.0) return 0.0;
  const glm::dvec3 d = glm::normalize(direction);
  // Project onto a cloud plane at unit height; far parts fade out towards the horizon.
  const double y = std::max(d.y, 0.02);
  const double px = 1.5 * d.x / y, pz = 1.5 * d.z / y;
  double n = 0.0, amplitude = 0.5, frequency = 1.0, total = 0.0;
  for (int octave = 0; octave < 5; ++octave) {
    n += amplitude * value_noise(mix64(p_.cloud_seed + octave), px * frequency, pz * frequency);
    total += amplitude;
    amplitude *= 0.5;
    frequency *= 2.0;
  }
  n /= total;
  // Higher cover lowers the noise level that counts as cloud.
  const double threshold = 0.75 - 0.5 * p_.cloud_cover;
  return smoothstep(threshold - 0.08, threshold + 0.08, n) * smoothstep(0.0, 0.08, d.y);
}

glm::dvec3 PreethamSky::radiance(const glm::dvec3& direction) const {
  if (direction.y < 0.0) return ground_rgb_;
  const glm::dvec3 clear = clear_sky_radiance(direction);
  const double c = cloud_cover_at(direction);
  if (c <= 0.0) return clear;
  // Clouds are grey, about as bright as the clear sky around them, brighter near the sun.
  const double y = luminance(clear.x, clear.y, clear.z);
  const double forward = std::pow(std::max(0.0, glm::dot(glm::normalize(direction), sun_dir_)), 8.0);
  const glm::dvec3 cloud(y * (1.1 + 2.0 * forward));
  return (1.0 - c) * clear + c * cloud;
}

Tensor PreethamSky::render(int height, int width) const {
  SL_CHECK(height >= 1 && width >= 1, "PreethamSky::render: size must be >= 1, got ", height, "x", width);
  Tensor out = Tensor::empty({3, height, width}, DType::F32);
  float* p = out.data<float>();
  const int64_t plane = static_cast<int64_t>(height) * width;
  parallel_for(height, 2, [&](int64_t r0, int64_t r1) {
    for (int64_t i = r0; i < r1; ++i)
      for (int j = 0; j < width; ++j) {
        const auto d = render::equirect::uv_to_direction(j + 0.5, i + 0.5, width, height);
        // A texel whose centre is at or above the horizon shows sky.
        const glm::dvec3 dir(d.x, std::fabs(d.y) < 1e-12 ? 0.0 : d.y, d.z);
        const glm::dvec3 l = radiance(dir);
        for (int c = 0; c < 3; ++c) p[c * plane + i * width + j] = static_cast<float>(l[c]);
      }
  });
  if (!p_.sun_disk) return out;
  // Splat the disk: stratified samples, uniform in solid angle over the cap, each carrying
  // L_sun·Ω_sun / N of energy into the texel it falls in, so Σ L·Ω gains exactly L_sun·Ω_sun.
  const glm::dvec3 helper = std::fabs(sun_dir_.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 t1 = glm::normalize(glm::cross(helper, sun_dir_)), t2 = glm::cross(sun_dir_, t1);
  const int side = 16;
  const double cos_r = std::cos(kSunAngularRadiusRad);
  const double energy = sun_solid_angle() / kSunSamples;
  for (int s = 0; s < kSunSamples; ++s) {
    const double a = ((s % side) + 0.5) / side, b = ((s / side) + 0.5) / side;
    const double cos_alpha = 1.0 - a * (1.0 - cos_r);
    const double sin_alpha = std::sqrt(std::max(0.0, 1.0 - cos_alpha * cos_alpha));
    const double phi = 2.0 * kPi * b;
    const glm::dvec3 d = cos_alpha * sun_dir_ + sin_alpha * (std::cos(phi) * t1 + std::sin(phi) * t2);
    const auto uv = render::equirect::direction_to_uv(d.x, d.y, d.z, width, height);
    const int col = std::clamp(static_cast<int>(std::floor(uv.u)), 0, width - 1);
    const int row = std::clamp(static_cast<int>(std::floor(uv.v)), 0, height - 1);
    const double omega = render::equirect::pixel_solid_angle(row, width, height);
    for (int c = 0; c < 3; ++c)
      p[c * plane + static_cast<int64_t>(row) * width + col] += static_cast<float>(sun_rgb_[c] * energy / omega);
  }
  return out;
}

SkyParams sample_sky_params(uint64_t seed, uint64_t index) {
  Rng rng(seed, index);
  SkyParams p;
  p.sun_elevation_rad = rng.uniform(0.0, 85.0) * kPi / 180.0;
  p.sun_azimuth_rad = rng.uniform(-kPi, kPi);
  p.turbidity = rng.uniform(2.0, 8.0);
  p.ground_albedo = rng.uniform(0.05, 0.4);
  const bool cloudy = rng.uniform() < 0.5;
  const double cover = rng.uniform(0.1, 0.7);
  p.cloud_cover = cloudy ? cover : 0.0;
  p.cloud_seed = rng.next_u64();
  return p;
}

}  // namespace sl::data
