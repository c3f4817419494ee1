// train/sun_distribution.h: the sun as a distribution over the upper hemisphere (issue 53).
// Cells of equal solid angle, a soft target peaked at the true sun, a cross-entropy that passes a
// float64 gradcheck and stays finite for extreme logits, the mirror image, and a readout at the
// mode that picks the larger of two separated peaks instead of a direction between them.
#include "train/sun_distribution.h"

#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "util/error.h"

namespace sl::test {
namespace {

using train::SunGrid;

glm::dvec3 sun(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * M_PI / 180.0, e = elevation_deg * M_PI / 180.0;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)) * 180.0 / M_PI;
}

const SunGrid kGrid{8, 32};

double elevation_of(const glm::dvec3& d) { return std::asin(glm::normalize(d).y) * 180.0 / M_PI; }

// A peaked distribution: the soft target of a narrow lobe at `s`, scaled to `mass`.
std::vector<double> peak(const glm::dvec3& s, double mass, double width_deg = 6.0) {
  std::vector<double> t = train::soft_target(kGrid, s, width_deg);
  for (double& v : t) v *= mass;
  return t;
}

TEST(SunDistribution, CellsAreUnitAboveTheHorizonAndOfEqualSolidAngle) {
  const Tensor d = train::cell_directions(kGrid, DType::F64);
  ASSERT_EQ(d.shape(), (Shape{256, 3}));
  const std::vector<double> v = d.to_vector();
  for (int64_t k = 0; k < 256; ++k) {
    const glm::dvec3 c(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
    EXPECT_NEAR(glm::length(c), 1.0, 1e-12);
    EXPECT_GT(c.y, 0.0);
    // Ring r holds sin(elevation) in [r/8, (r+1)/8): equal areas on the sphere (Archimedes).
    const int64_t ring = k / 32;
    EXPECT_NEAR(c.y, (ring + 0.5) / 8.0, 1e-12);
  }
  // Sector 16's centre is at azimuth +5.625°, just right of the view's axis (−Z).
  const glm::dvec3 c16(v[3 * 16], v[3 * 16 + 1], v[3 * 16 + 2]);
  EXPECT_NEAR(std::atan2(c16.x, -c16.z) * 180.0 / M_PI, 5.625, 1e-9);
}

TEST(SunDistribution, TheSoftTargetPeaksAtTheSunAndSumsToOne) {
  // Within a cell of the 8 × 32 grid: its rings are 7.2° tall at the horizon and 29° at the top
  // (equal areas), so a sun above about 60° is read coarsely by this grid (the release's is 16 × 64).
  for (const glm::dvec3& s : {sun(0, 20), sun(-170, 5), sun(95, 55), sun(40, -10)}) {
    const std::vector<double> t = train::soft_target(kGrid, s, 8.0);
    double total = 0.0;
    for (const double v : t) {
      EXPECT_TRUE(std::isfinite(v) && v >= 0.0);
      total += v;
    }
    EXPECT_NEAR(total, 1.0, 1e-12);
    const train::SunReadout r = train::read_sun_distribution(kGrid, t);
    const glm::dvec3 expected = s.y < 0 ? sun(40, 0) : s;
    EXPECT_LT(angle_deg(r.direction, expected), 7.2) << "sun (" << s.x << ", " << s.y << ", " << s.z << ")";
  }
  // Far narrower than a cell: all the mass on the nearest cell, never 0/0.
  const std::vector<double> t = train::soft_target(kGrid, sun(10, 30), 1e-4);
  double total = 0.0;
  for (const double v : t) total += v;
  EXPECT_NEAR(total, 1.0, 1e-12);
  EXPECT_THROW(train::soft_target(kGrid, glm::dvec3(0.0), 8.0), Error);
  EXPECT_THROW(train::soft_target(kGrid, sun(0, 20), 0.0), Error);
}

// The test: two separated peaks read out at the larger one, not between them. The mean
// of these two suns (in front and behind, both at 20°) would be near the zenith.
TEST(SunDistribution, TwoSeparatedPeaksReadOutAtTheLargerOne) {
  const glm::dvec3 front = sun(10, 20), back = sun(-170, 20);
  for (const double larger : {0.55, 0.7}) {
    std::vector<double> p = peak(front, larger), q = peak(back, 1.0 - larger);
    for (size_t k = 0; k < p.size(); ++k) p[k] += q[k];
    const train::SunReadout r = train::read_sun_distribution(kGrid, p);
    EXPECT_LT(angle_deg(r.direction, front), 4.0);
    EXPECT_NEAR(r.confidence, larger, 0.02);
    // And the other way round.
    std::vector<double> m = peak(back, larger), n = peak(front, 1.0 - larger);
    for (size_t k = 0; k < m.size(); ++k) m[k] += n[k];
    EXPECT_LT(angle_deg(train::read_sun_distribution(kGrid, m).direction, back), 4.0);
  }
  // A uniform distribution is as unsure as it gets: its confidence is the cap's share.
  const std::vector<double> uniform(256, 1.0 / 256);
  EXPECT_LT(train::read_sun_distribution(kGrid, uniform).confidence, 0.1);
}

// A second opinion on the azimuth alone (the glare detector's azimuth head) moves the mode to the
// peak it favours; weight 0 and a flat opinion change nothing; bad input is refused.
TEST(SunDistribution, AnAzimuthOpinionReweighsThePeaks) {
  const glm::dvec3 front = sun(10, 20), back = sun(-170, 20);
  std::vector<double> p = peak(front, 0.6), q = peak(back, 0.4);
  for (size_t k = 0; k < p.size(); ++k) p[k] += q[k];
  ASSERT_LT(angle_deg(train::read_sun_distribution(kGrid, p).direction, front), 4.0);
  // 8 sectors; the two behind the camera (|azimuth| > 135°) three times as likely as the others.
  std::vector<double> behind(8, 1.0);
  behind[0] = behind[7] = 3.0;
  const std::vector<double> w = train::weigh_by_azimuth(kGrid, p, behind, 1.0);
  double total = 0.0;
  for (const double v : w) total += v;
  EXPECT_NEAR(total, 1.0, 1e-12);
  const train::SunReadout r = train::read_sun_distribution(kGrid, w);
  EXPECT_LT(angle_deg(r.direction, back), 4.0);
  EXPECT_NEAR(r.confidence, 0.4 * 3.0 / (0.4 * 3.0 + 0.6), 0.02);
  // At a weight of 0.25 the opinion is too weak to overturn the front peak.
  EXPECT_LT(angle_deg(train::read_sun_distribution(kGrid, train::weigh_by_azimuth(kGrid, p, behind, 0.25)).direction, front), 4.0);
  // Weight 0 returns the same values; a flat opinion the same up to rounding.
  EXPECT_EQ(train::weigh_by_azimuth(kGrid, p, behind, 0.0), p);
  const std::vector<double> flat = train::weigh_by_azimuth(kGrid, p, std::vector<double>(8, 0.125), 2.0);
  double sum_p = 0.0;
  for (const double v : p) sum_p += v;
  for (size_t k = 0; k < p.size(); ++k) EXPECT_NEAR(flat[k], p[k] / sum_p, 1e-12);
  // A zero opinion never rules a cell out: the floor keeps every cell positive.
  std::vector<double> zero_front(8, 0.0);
  zero_front[0] = 1.0;
  for (const double v : train::weigh_by_azimuth(kGrid, p, zero_front, 3.0)) EXPECT_TRUE(std::isfinite(v));
  EXPECT_THROW(train::weigh_by_azimuth(kGrid, p, {}, 1.0), Error);
  EXPECT_THROW(train::weigh_by_azimuth(kGrid, p, behind, -1.0), Error);
  EXPECT_THROW(train::weigh_by_azimuth(kGrid, p, behind, std::nan("")), Error);
  EXPECT_THROW(train::weigh_by_azimuth(kGrid, p, {1.0, -1.0}, 1.0), Error);
  EXPECT_THROW(train::weigh_by_azimuth(kGrid, std::vector<double>(3, 1.0), behind, 1.0), Error);
}

// A second opinion per cell, as a likelihood ratio: a factor of 4 on the smaller peak's cells
// overturns the larger one; weight 0 and equal factors change nothing; nothing is ruled out.
TEST(SunDistribution, ACellOpinionReweighsThePeaks) {
  const glm::dvec3 high = sun(30, 50), low = sun(-60, 10);
  std::vector<double> p = peak(high, 0.6), q = peak(low, 0.4);
  for (size_t k = 0; k < p.size(); ++k) p[k] += q[k];
  ASSERT_LT(angle_deg(train::read_sun_distribution(kGrid, p).direction, high), 4.0);
  std::vector<double> f(p.size(), 1.0);
  for (int64_t k = 0; k < kGrid.cells(); ++k)
    if (k / kGrid.azimuth_bins < 2) f[size_t(k)] = 4.0;  // the two rings nearest the horizon (< 14.5°)
  const std::vector<double> w = train::weigh_by_cells(kGrid, p, f, 1.0);
  double total = 0.0;
  for (const double v : w) total += v;
  EXPECT_NEAR(total, 1.0, 1e-12);
  EXPECT_LT(angle_deg(train::read_sun_distribution(kGrid, w).direction, low), 6.0);
  EXPECT_LT(elevation_of(train::read_sun_distribution(kGrid, w).direction), 15.0);
  EXPECT_LT(angle_deg(train::read_sun_distribution(kGrid, train::weigh_by_cells(kGrid, p, f, 0.05)).direction, high), 4.0);
  EXPECT_EQ(train::weigh_by_cells(kGrid, p, f, 0.0), p);
  const std::vector<double> flat = train::weigh_by_cells(kGrid, p, std::vector<double>(p.size(), 7.0), 2.0);
  double sum_p = 0.0;
  for (const double v : p) sum_p += v;
  for (size_t k = 0; k < p.size(); ++k) EXPECT_NEAR(flat[k], p[k] / sum_p, 1e-12);
  for (const double v : train::weigh_by_cells(kGrid, p, std::vector<double>(p.size(), 0.0), 3.0)) {
    EXPECT_TRUE(std::isfinite(v));
    EXPECT_GT(v, 0.0);  // p is positive everywhere; the floor keeps it so
  }
  // weigh_by_azimuth is weigh_by_cells with a factor per sector: the same bits.
  std::vector<double> behind(8, 1.0), per_cell(p.size());
  behind[0] = behind[7] = 3.0;
  for (size_t k = 0; k < p.size(); ++k) per_cell[k] = behind[(k % size_t(kGrid.azimuth_bins)) * 8 / size_t(kGrid.azimuth_bins)];
  EXPECT_EQ(train::weigh_by_cells(kGrid, p, per_cell, 1.5), train::weigh_by_azimuth(kGrid, p, behind, 1.5));
  EXPECT_THROW(train::weigh_by_cells(kGrid, p, std::vector<double>(3, 1.0), 1.0), Error);
  EXPECT_THROW(train::weigh_by_cells(kGrid, p, f, -1.0), Error);
  EXPECT_THROW(train::weigh_by_cells(kGrid, p, f, std::nan("")), Error);
  f[5] = std::nan("");
  EXPECT_THROW(train::weigh_by_cells(kGrid, p, f, 1.0), Error);
}

// Every cell's centre lies in that cell; below the horizon there is none.
TEST(SunDistribution, ADirectionFallsInTheCellWhoseCentreItIs) {
  const Tensor c = train::cell_directions(kGrid, DType::F64);
  const double* d = c.data<double>();
  for (int64_t k = 0; k < kGrid.cells(); ++k) {
    const glm::dvec3 dir(d[3 * k], d[3 * k + 1], d[3 * k + 2]);
    EXPECT_EQ(train::cell_of_direction(kGrid, dir), k);
    EXPECT_EQ(train::cell_of_direction(kGrid, 5.0 * dir), k);
  }
  EXPECT_EQ(train::cell_of_direction(kGrid, {0.0, 1.0, 0.0}) / kGrid.azimuth_bins, kGrid.elevation_bins - 1);  // the zenith
  EXPECT_EQ(train::cell_of_direction(kGrid, sun(0, -5)), -1);
  EXPECT_EQ(train::cell_of_direction(kGrid, sun(-180, 0)), 0);  // the horizon, azimuth −180°: ring 0, sector 0
  EXPECT_THROW(train::cell_of_direction(kGrid, {0.0, 0.0, 0.0}), Error);
  EXPECT_THROW(train::cell_of_direction(kGrid, {std::nan(""), 1.0, 0.0}), Error);
}

// An uncertain elevation reads at its median in degrees, not where the cells are densest. At
// one azimuth, the mass is spread evenly per degree over elevations 10°-50°: the median is 30°.
// The equal-area rings are taller the higher they lie, so the densest cell is the ring over
// 38.7°-48.6° (at 43.6°), where the mode alone would read; the old readout answered there.
TEST(SunDistribution, AnUncertainElevationReadsAtItsMedianNotTheDensestCell) {
  std::vector<double> p(static_cast<size_t>(kGrid.cells()), 0.0);
  const int64_t sector = 19;  // azimuth centre −180° + 19.5 · 11.25° = 39.375°
  for (int64_t r = 0; r < kGrid.elevation_bins; ++r) {
    const double lo = std::asin(r / 8.0) * 180.0 / M_PI, hi = std::asin(std::min(1.0, (r + 1) / 8.0)) * 180.0 / M_PI;
    p[static_cast<size_t>(r * kGrid.azimuth_bins + sector)] = std::max(0.0, std::min(hi, 50.0) - std::max(lo, 10.0));
  }
  const train::SunReadout r = train::read_sun_distribution(kGrid, p);
  const double elevation = std::asin(r.direction.y) * 180.0 / M_PI;
  EXPECT_NEAR(elevation, 30.0, 0.5);
  EXPECT_NEAR(std::atan2(r.direction.x, -r.direction.z) * 180.0 / M_PI, 39.375, 1e-6);
  EXPECT_NEAR(glm::length(r.direction), 1.0, 1e-12);
  EXPECT_EQ(r.mode_cell, 5 * kGrid.azimuth_bins + sector);
}

TEST(SunDistribution, TheMirrorImageMirrorsTheReadout) {
  const glm::dvec3 s = sun(37, 25);
  const std::vector<double> m = train::mirror_cells(kGrid, train::soft_target(kGrid, s, 8.0));
  const train::SunReadout r = train::read_sun_distribution(kGrid, m);
  EXPECT_LT(angle_deg(r.direction, glm::dvec3(-s.x, s.y, s.z)), 4.0);
  // Twice is the identity.
  const std::vector<double> t = train::soft_target(kGrid, s, 8.0);
  EXPECT_EQ(train::mirror_cells(kGrid, train::mirror_cells(kGrid, t)), t);
}

TEST(SunDistribution, TheCrossEntropyPassesAFloat64Gradcheck) {
  const int64_t n = 3, k = kGrid.cells();
  std::vector<double> z(n * k), t;
  for (int64_t i = 0; i < n * k; ++i) z[i] = std::sin(0.37 * i) * 2.0;
  for (const glm::dvec3& s : {sun(0, 20), sun(120, 50), sun(-60, 5)}) {
    const auto row = train::soft_target(kGrid, s, 8.0);
    t.insert(t.end(), row.begin(), row.end());
  }
  const Tensor logits = Tensor::from_vector(z, {n, k}, DType::F64);
  const Tensor targets = Tensor::from_vector(t, {n, k}, DType::F64),
               weights = Tensor::from_vector({1.0, 0.5, 0.0}, {n}, DType::F64);
  const GradcheckResult r = gradcheck(
      [&](const TensorList& in) { return train::sun_distribution_loss(in[0], targets, weights); }, {logits});
  EXPECT_TRUE(r.ok) << r.message;
  // The value: the weighted mean of logsumexp(z) − Σ t z.
  const Tensor loss = train::sun_distribution_loss(logits, targets, weights);
  double expected = 0.0;
  for (int64_t i = 0; i < n; ++i) {
    double m = -1e300, s = 0.0, tz = 0.0;
    for (int64_t j = 0; j < k; ++j) m = std::max(m, z[i * k + j]);
    for (int64_t j = 0; j < k; ++j) s += std::exp(z[i * k + j] - m), tz += t[i * k + j] * z[i * k + j];
    expected += (i == 0 ? 1.0 : i == 1 ? 0.5 : 0.0) * (m + std::log(s) - tz);
  }
  EXPECT_NEAR(loss.item(), expected / n, 1e-12);
}

// The front/back loss: the two halves' cross-entropy. Its value against a direct computation,
// a float64 gradcheck, finite for extreme logits, and which cells are "in front": a
// distribution all behind the camera pays for a sun in front, not for one behind.
TEST(SunDistribution, TheFrontBackLossWeighsTheTwoHalves) {
  const int64_t n = 3, k = kGrid.cells();
  std::vector<double> z(n * k), t;
  for (int64_t i = 0; i < n * k; ++i) z[i] = std::cos(0.23 * i) * 3.0;
  for (const glm::dvec3& s : {sun(10, 20), sun(170, 50), sun(89, 5)}) {
    const auto row = train::soft_target(kGrid, s, 8.0);
    t.insert(t.end(), row.begin(), row.end());
  }
  const Tensor logits = Tensor::from_vector(z, {n, k}, DType::F64);
  const Tensor targets = Tensor::from_vector(t, {n, k}, DType::F64),
               weights = Tensor::from_vector({1.0, 0.5, 2.0}, {n}, DType::F64);
  const GradcheckResult r = gradcheck(
      [&](const TensorList& in) { return train::sun_half_loss(kGrid, in[0], targets, weights); }, {logits});
  EXPECT_TRUE(r.ok) << r.message;
  double expected = 0.0;
  const double w[3] = {1.0, 0.5, 2.0};
  for (int64_t i = 0; i < n; ++i) {
    double pf = 0, pall = 0, y = 0;
    for (int64_t c = 0; c < k; ++c) {
      const int64_t j = c % kGrid.azimuth_bins;
      const double az = -180.0 + (j + 0.5) * 360.0 / kGrid.azimuth_bins;
      const double e = std::exp(z[i * k + c]);
      pall += e;
      if (std::fabs(az) < 90.0) pf += e, y += t[i * k + c];
    }
    const double p = pf / pall;
    expected += w[i] * -(y * std::log(p) + (1 - y) * std::log(1 - p));
  }
  EXPECT_NEAR(train::sun_half_loss(kGrid, logits, targets, weights).item(), expected / n, 1e-12);

  // All mass behind (a peak at azimuth 180°): a sun in front costs much, one behind little.
  std::vector<double> behind(static_cast<size_t>(k));
  const auto b = train::soft_target(kGrid, sun(180, 30), 8.0);
  for (int64_t c = 0; c < k; ++c) behind[c] = std::log(b[c] + 1e-12);
  const Tensor zb = Tensor::from_vector(behind, {1, k}, DType::F64), one = Tensor::from_vector({1.0}, {1}, DType::F64);
  const auto target = [&](const glm::dvec3& s) { return Tensor::from_vector(train::soft_target(kGrid, s, 8.0), {1, k}, DType::F64); };
  EXPECT_GT(train::sun_half_loss(kGrid, zb, target(sun(0, 30)), one).item(), 10.0);
  EXPECT_LT(train::sun_half_loss(kGrid, zb, target(sun(150, 30)), one).item(), 1e-3);

  std::vector<double> extreme(static_cast<size_t>(k), -1e4);
  extreme[3] = 1e4;
  Tensor ze = Tensor::from_vector(extreme, {1, k}).to(DType::F32);
  ze.set_requires_grad(true);
  const Tensor loss = train::sun_half_loss(kGrid, ze, target(sun(0, 30)).to(DType::F32), Tensor::from_vector({1.0}, {1}));
  EXPECT_TRUE(std::isfinite(loss.item()));
  backward(loss);
  for (const double g : ze.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  EXPECT_THROW(train::sun_half_loss(SunGrid{8, 30}, Tensor::zeros({1, 240}), Tensor::zeros({1, 240}), Tensor::ones({1})), Error);
}

TEST(SunDistribution, ExtremeLogitsGiveAFiniteLossAndGradient) {
  const int64_t k = kGrid.cells();
  std::vector<double> z(k, -1e4);
  z[7] = 1e4;  // a certain network, certain of the wrong cell
  Tensor logits = Tensor::from_vector(z, {1, k}).to(DType::F32);
  logits.set_requires_grad(true);
  const auto t = train::soft_target(kGrid, sun(90, 40), 8.0);
  const Tensor loss = train::sun_distribution_loss(logits, Tensor::from_vector(t, {1, k}), Tensor::from_vector({1.0}, {1}));
  EXPECT_TRUE(std::isfinite(loss.item()));
  backward(loss);
  for (const double g : logits.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  // Bad probabilities are refused, naming the value.
  std::vector<double> p(k, 0.0);
  EXPECT_THROW(train::read_sun_distribution(kGrid, p), Error);
  p[3] = std::nan("");
  EXPECT_THROW(train::read_sun_distribution(kGrid, p), Error);
  EXPECT_THROW(train::validate(SunGrid{8, 0}), Error);
  EXPECT_THROW(train::validate(SunGrid{8, 31}), Error);
}

// Low suns weighed up: 1 above the threshold, 1 + boost at (and below) the horizon, linear
// between, whatever the direction's length; bad arguments are refused.
TEST(SunDistribution, LowSunsWeighUpLinearlyBelowTheThreshold) {
  EXPECT_DOUBLE_EQ(train::low_sun_weight(sun(10, 60), 2.0, 30.0), 1.0);
  EXPECT_DOUBLE_EQ(train::low_sun_weight(sun(10, 30), 2.0, 30.0), 1.0);
  EXPECT_NEAR(train::low_sun_weight(sun(-120, 15), 2.0, 30.0), 2.0, 1e-12);
  EXPECT_NEAR(train::low_sun_weight(5.0 * sun(45, 10), 2.0, 30.0), 1.0 + 2.0 * 20.0 / 30.0, 1e-12);
  EXPECT_NEAR(train::low_sun_weight(sun(0, 0), 2.0, 30.0), 3.0, 1e-12);
  EXPECT_NEAR(train::low_sun_weight(glm::dvec3(0.0, -1.0, 1.0), 2.0, 30.0), 3.0, 1e-12);  // below: as the horizon
  EXPECT_DOUBLE_EQ(train::low_sun_weight(sun(0, 5), 0.0, 30.0), 1.0);                     // off
  EXPECT_THROW(train::low_sun_weight(sun(0, 5), -1.0, 30.0), Error);
  EXPECT_THROW(train::low_sun_weight(sun(0, 5), 1.0, 0.0), Error);
  EXPECT_THROW(train::low_sun_weight(glm::dvec3(0.0), 1.0, 30.0), Error);
}

}  // namespace
}  // namespace sl::test
