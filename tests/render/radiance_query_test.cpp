#include "render/radiance_query.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "render/environment_map.h"
#include "render/radiance_march.h"

using sl::render::env_lookup;
using sl::render::parse_sample_spacing;
using sl::render::radiance_query;
using sl::render::RadianceQueryOptions;
using sl::render::RadianceQueryStats;
using sl::render::sample_spacing_name;
using sl::render::SampleSpacing;
using sl::render::vsg_activate;
using sl::render::VsgGrid;

namespace sl::test {
namespace {

VsgGrid small_grid() {
  VsgGrid g;
  g.dims = {4, 4, 2};
  g.center = {0, 0, 0};
  g.extent_neg = {10, 4, 10};
  g.extent_pos = {10, 6, 10};
  g.log_scale_m = 2.0;
  return g;
}

// Random activated VSG parameters with alpha in a moderate range.
Tensor random_vsg(const VsgGrid& g, uint64_t seed, DType dt, double alpha_lo = 0.05, double alpha_hi = 0.6) {
  Tensor raw = Tensor::uniform({8, g.dims[0], g.dims[1], g.dims[2]}, -1, 1, seed, dt);
  Tensor p = vsg_activate(raw, 0).detach().clone();
  Tensor alpha = Tensor::uniform({1, g.dims[0], g.dims[1], g.dims[2]}, alpha_lo, alpha_hi, seed + 1, dt);
  slice(p, 0, 7, 8).copy_(alpha);
  return p;
}

struct Rays {
  Tensor origins, dirs;
};

Rays random_rays(int64_t n, uint64_t seed, DType dt) {
  return {Tensor::uniform({n, 3}, -2, 2, seed, dt), Tensor::uniform({n, 3}, -1, 1, seed + 1, dt)};
}

TEST(VsgGrid, LogProjectionIsInvertibleAndMapsTheEdgesToTheGridBounds) {
  VsgGrid g;  // the paper's 300 x 300 x 80 m at 64 x 64 x 16
  for (double x : {-150.0, -37.5, -0.01, 0.0, 0.3, 12.0, 149.99})
    for (double y : {g.center.y - 5.0, g.center.y, g.center.y + 75.0})
      for (double z : {-150.0, 7.0, 150.0}) {
        const glm::dvec3 p(x, y, z);
        const glm::dvec3 v = g.to_voxel(p);
        const glm::dvec3 back = g.to_world(v);
        EXPECT_NEAR(glm::length(back - p), 0.0, 1e-9) << x << "," << y << "," << z;
        for (int a = 0; a < 3; ++a) {
          EXPECT_GE(v[a], -1e-9);
          EXPECT_LE(v[a], double(g.dims[a]) + 1e-9);
        }
      }
  EXPECT_NEAR(g.to_voxel({150, g.center.y, 0}).x, 64.0, 1e-9);
  EXPECT_NEAR(g.to_voxel({0, g.center.y + 75, 0}).z, 16.0, 1e-9);
  EXPECT_NEAR(g.to_voxel({0, g.center.y - 5, -150}).z, 0.0, 1e-9);
  EXPECT_NEAR(g.to_voxel({0, g.center.y - 5, -150}).y, 0.0, 1e-9);
  // Voxels grow with distance: the first is under a metre, the last tens of metres.
  const double near_m = g.to_world({33, 32, 8}).x - g.to_world({32, 32, 8}).x;
  const double far_m = g.to_world({64, 32, 8}).x - g.to_world({63, 32, 8}).x;
  EXPECT_LT(near_m, 1.0);
  EXPECT_GT(far_m, 10.0);
}

// VoxelMapper (the log projection with its denominators computed once, for loops over many
// points) is to_voxel bit for bit: inside, outside and on the edges of a grid that is not centred
// on the origin, for offsets of either sign on every axis.
TEST(VsgGrid, VoxelMapperIsToVoxelBitForBit) {
  VsgGrid g;
  g.center = {3.5, 1.65, -7.25};
  g.extent_neg = {140.0, 4.0, 120.0};
  const sl::render::VoxelMapper mapper(g);
  const std::vector<double> pts = Tensor::uniform({3000}, -200.0, 200.0, 41).to_vector();
  for (size_t i = 0; i + 2 < pts.size(); i += 3) {
    const glm::dvec3 p = g.center + glm::dvec3(pts[i], 0.25 * pts[i + 1], pts[i + 2]);
    const glm::dvec3 a = g.to_voxel(p), b = mapper(p);
    for (int k = 0; k < 3; ++k) ASSERT_EQ(a[k], b[k]) << "point " << i / 3 << " axis " << k;
  }
  for (const glm::dvec3& p : {g.center, g.center - g.extent_neg, g.center + g.extent_pos})
    EXPECT_EQ(g.to_voxel(p), mapper(p));
}

TEST(VsgActivate, MapsAnyRawValueToValidParameters) {
  Tensor raw = Tensor::from_vector({-1e4, 0, 1e4, 0, 0, 0, -1e4, 1e4}, {8, 1, 1, 1}, DType::F64).set_requires_grad(true);
  Tensor p = vsg_activate(raw, 0);
  backward(sum(p));
  const auto v = p.to_vector();
  EXPECT_GE(v[0], 0.0);
  EXPECT_DOUBLE_EQ(v[2], 1e4);
  EXPECT_GE(v[6], VsgGrid::kMinSharpness);
  EXPECT_DOUBLE_EQ(v[7], 1.0);
  for (double gv : raw.grad().to_vector()) EXPECT_TRUE(std::isfinite(gv));
}

// The one-op float32 path equals the composite path (softplus / sigmoid of channel slices,
// add_scalar, concat: what a non-contiguous input takes) in values and gradients, for the
// predictor's layout (channels in dim 1), channels first, odd spatial sizes and extreme raw values.
TEST(VsgActivate, Float32OneOpEqualsTheCompositePath) {
  for (const auto& [shape, dim] : {std::pair<Shape, int64_t>{{2, 8, 5, 7, 3}, 1}, {{8, 3, 1, 33}, 0},
                                   {{1, 8, 64}, 1}, {{3, 8, 2, 2, 2}, -4}}) {
    Tensor raw = Tensor::uniform(shape, -30, 30, 61, DType::F32);
    raw.data<float>()[0] = 0.0f;
    raw.data<float>()[1] = -0.0f;
    const Tensor upstream = Tensor::uniform(shape, -1, 1, 62, DType::F32);
    Tensor a = raw.clone().set_requires_grad(true);
    // The same values as a view into a wider tensor: non-contiguous rows, so the composite path.
    const int64_t last = static_cast<int64_t>(shape.size()) - 1;
    Tensor wide = concat({raw, Tensor::uniform(shape, -1, 1, 63, DType::F32)}, last).set_requires_grad(true);
    const Tensor b = slice(wide, last, 0, shape[last]);
    ASSERT_FALSE(b.is_contiguous());
    const Tensor ya = vsg_activate(a, dim), yb = vsg_activate(b, dim);
    backward(sum(mul(ya, upstream)));
    backward(sum(mul(yb, upstream)));
    EXPECT_EQ(ya.to_vector(), yb.to_vector());
    EXPECT_EQ(a.grad().to_vector(), slice(wide.grad(), last, 0, shape[last]).contiguous().to_vector());
  }
}

TEST(RadianceQuery, EmptyVolumeReturnsTheSkyWithUnitTransmittance) {
  const VsgGrid g = small_grid();
  Tensor vsg = Tensor::zeros({8, 4, 4, 2}, DType::F64);  // alpha = 0 everywhere
  Tensor env = Tensor::uniform({3, 8, 16}, 0.5, 2, 3, DType::F64);
  const Rays r = random_rays(50, 4, DType::F64);
  for (bool prune : {true, false}) {
    RadianceQueryOptions opt;
    opt.prune = prune;
    const auto q = radiance_query(vsg, env, r.origins, r.dirs, g, opt);
    const Tensor sky = env_lookup(env, r.dirs);
    for (int64_t i = 0; i < 50; ++i) {
      EXPECT_DOUBLE_EQ(q.transmittance.at({i}), 1.0);
      for (int64_t c = 0; c < 3; ++c) EXPECT_NEAR(q.radiance.at({i, c}), sky.at({i, c}), 1e-12);
      EXPECT_DOUBLE_EQ(q.depth.at({i}), 0.0);
    }
  }
}

TEST(RadianceQuery, OpaqueVolumeHidesTheSkyAndShowsTheFirstLobe) {
  const VsgGrid g = small_grid();
  Tensor vsg = Tensor::zeros({8, 4, 4, 2}, DType::F64);
  slice(vsg, 0, 0, 3).fill_(2.0);   // c
  slice(vsg, 0, 4, 5).fill_(1.0);   // μ = +y
  slice(vsg, 0, 6, 7).fill_(1e-3);  // nearly isotropic lobe
  slice(vsg, 0, 7, 8).fill_(1.0);   // opaque
  Tensor env = Tensor::full({3, 8, 16}, 1e5, DType::F64);  // a blinding sky must not leak
  Tensor o = Tensor::zeros({1, 3}, DType::F64), d = Tensor::from_vector({0.3, 0.2, -1}, {1, 3}, DType::F64);
  const auto q = radiance_query(vsg, env, o, d, g);
  EXPECT_DOUBLE_EQ(q.transmittance.item(), 0.0);
  // The first sample's lobe, seen from x: 2·exp(−λ|−l̂ − μ|²/2) with μ = +y.
  const glm::dvec3 v = -glm::normalize(glm::dvec3(0.3, 0.2, -1));
  const double dist2 = glm::dot(v - glm::dvec3(0, 1, 0), v - glm::dvec3(0, 1, 0));
  EXPECT_NEAR(q.radiance.at({0, 0}), 2.0 * std::exp(-1e-3 * dist2 / 2), 1e-12);
}

TEST(RadianceQuery, GradcheckNearestAndTrilinear) {
  const VsgGrid g = small_grid();
  for (int variant = 0; variant < 3; ++variant) {
    const bool tri = variant == 1;
    RadianceQueryOptions opt;
    opt.samples = 6;
    opt.trilinear = tri;
    if (variant == 2) opt.spacing = SampleSpacing::kGrid;
    opt.prune = false;  // pruning thresholds are discontinuous; checked separately below
    const Rays r = random_rays(5, 10, DType::F64);
    auto f = [&](const TensorList& in) {
      const auto q = radiance_query(in[0], in[1], r.origins, r.dirs, g, opt);
      // One scalar per output: all three outputs are checked at once.
      return concat({reshape(q.radiance, {-1}), q.transmittance, mul_scalar(q.depth, 0.1)}, 0);
    };
    const GradcheckResult res = gradcheck(f, {random_vsg(g, 11, DType::F64), Tensor::uniform({3, 4, 8}, 0.1, 2, 12, DType::F64)});
    EXPECT_TRUE(res.ok) << (tri ? "trilinear: " : "nearest: ") << sample_spacing_name(opt.spacing) << ": "
                        << res.message;
  }
}

// Eq. 1 with spacing kGrid: samples equi-spaced in the log-projected grid. Along a ray from the
// grid centre down the +x axis, K = 32 samples then visit each of the 32 voxels between the
// centre and the edge exactly once; spaced evenly in metres (4.7 m apart) they skip the sub-metre
// voxels near the camera. A single opaque voxel shows which voxels a ray's samples reach.
TEST(RadianceQuery, GridSpacingVisitsEveryVoxelAlongTheRayOnce) {
  VsgGrid g;  // 64 x 64 x 16 over 300 x 300 x 80 m, r0 = 5 m
  g.center = {0, 0, 0};
  const int64_t X = g.dims[0], Y = g.dims[1], Z = g.dims[2];
  const Tensor env = Tensor::zeros({3, 8, 16}, DType::F64);
  const Tensor o = Tensor::from_vector({0.0, 0.0, 0.0}, {1, 3}, DType::F64);
  const Tensor d = Tensor::from_vector({1.0, 0.0, 0.0}, {1, 3}, DType::F64);
  const glm::dvec3 c = g.to_voxel(g.center);
  const int64_t iy = int64_t(c.y), iz = int64_t(c.z);
  auto seen = [&](SampleSpacing spacing, int64_t ix) {
    Tensor vsg = Tensor::zeros({8, X, Y, Z}, DType::F64);
    const int64_t vox = X * Y * Z, v = (ix * Y + iy) * Z + iz;
    double* p = vsg.data<double>();
    for (int ch = 0; ch < 3; ++ch) p[ch * vox + v] = 1.0;  // c = 1
    p[4 * vox + v] = 1.0;                                  // μ = +y
    p[6 * vox + v] = 1e-3;                                 // nearly isotropic
    p[7 * vox + v] = 1.0;                                  // opaque
    RadianceQueryOptions opt;
    opt.samples = 32;
    opt.spacing = spacing;
    return radiance_query(vsg, env, o, d, g, opt).transmittance.item() < 0.5;
  };
  int grid_seen = 0, metric_seen = 0;
  for (int64_t ix = X / 2; ix < X; ++ix) {
    grid_seen += seen(SampleSpacing::kGrid, ix);
    metric_seen += seen(SampleSpacing::kMetric, ix);
  }
  EXPECT_EQ(grid_seen, 32);
  EXPECT_LE(metric_seen, 24);  // even spacing in metres skips the small near voxels (20 of 32)
  // Near the camera in particular: the first three voxels (under 2 m) are all reached.
  for (int64_t ix = X / 2; ix < X / 2 + 3; ++ix) {
    EXPECT_TRUE(seen(SampleSpacing::kGrid, ix)) << ix;
    EXPECT_FALSE(seen(SampleSpacing::kMetric, ix)) << ix;
  }
}

// With nearest lookup, grid spacing composites each voxel crossed once: once K reaches the voxel
// count along the ray, more samples change nothing (even spacing applies a voxel's α once per
// sample that lands in it, so its transmittance keeps falling with K).
TEST(RadianceQuery, GridSpacingCompositesEachVoxelOnceHoweverLargeK) {
  VsgGrid g;
  g.center = {0, 0, 0};
  const Tensor vsg = random_vsg(g, 31, DType::F64, 0.02, 0.1);
  const Tensor env = Tensor::uniform({3, 8, 16}, 0.5, 2, 32, DType::F64);
  const Tensor o = Tensor::from_vector({0.0, 0.0, 0.0}, {1, 3}, DType::F64);
  const Tensor d = Tensor::from_vector({1.0, 0.0, 0.0}, {1, 3}, DType::F64);
  auto query = [&](SampleSpacing spacing, int K) {
    RadianceQueryOptions opt;
    opt.samples = K;
    opt.spacing = spacing;
    opt.prune = false;
    return radiance_query(vsg, env, o, d, g, opt);
  };
  const auto g32 = query(SampleSpacing::kGrid, 32), g512 = query(SampleSpacing::kGrid, 512);
  EXPECT_NEAR(g512.transmittance.item(), g32.transmittance.item(), 1e-12);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(g512.radiance.at({0, c}), g32.radiance.at({0, c}), 1e-12);
  const auto m32 = query(SampleSpacing::kMetric, 32), m512 = query(SampleSpacing::kMetric, 512);
  EXPECT_LT(m512.transmittance.item(), 0.5 * m32.transmittance.item());
}

TEST(RadianceQuery, SampleSpacingNamesRoundTripAndUnknownNamesAreErrors) {
  for (SampleSpacing s : {SampleSpacing::kMetric, SampleSpacing::kGrid})
    EXPECT_EQ(parse_sample_spacing(sample_spacing_name(s)), s);
  try {
    parse_sample_spacing("log");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'log'"), std::string::npos) << e.what();
  }
}

TEST(RadianceQuery, GradcheckWithPruningAwayFromThresholds) {
  const VsgGrid g = small_grid();
  RadianceQueryOptions opt;
  opt.samples = 5;
  const Rays r = random_rays(4, 20, DType::F64);
  auto f = [&](const TensorList& in) { return radiance_query(in[0], in[1], r.origins, r.dirs, g, opt).radiance; };
  const GradcheckResult res =
      gradcheck(f, {random_vsg(g, 21, DType::F64, 0.2, 0.7), Tensor::uniform({3, 4, 8}, 0.1, 2, 22, DType::F64)});
  EXPECT_TRUE(res.ok) << res.message;
}

TEST(RadianceQuery, PrunedMatchesUnprunedWithinTheDocumentedBound) {
  VsgGrid g;
  g.dims = {16, 16, 8};
  Tensor vsg = random_vsg(g, 30, DType::F32, 0.0, 0.9);
  // A third of the voxels are empty; a sun of 1e5 sits in the sky.
  Tensor mask = gt(Tensor::uniform({1, 16, 16, 8}, 0, 1, 31), Tensor::scalar(0.33f));
  slice(vsg, 0, 7, 8).copy_(mul(slice(vsg, 0, 7, 8), mask));
  Tensor env = Tensor::full({3, 16, 32}, 1.0f);
  env.data<float>()[5 * 32 + 7] = 1e5f;
  Tensor o = Tensor::zeros({4000, 3});
  slice(o, 1, 1, 2).fill_(1.6);
  Tensor d = Tensor::uniform({4000, 3}, -1, 1, 32);
  RadianceQueryOptions full, pruned;
  full.prune = false;
  RadianceQueryStats stats;
  const auto a = radiance_query(vsg, env, o, d, g, full);
  const auto b = radiance_query(vsg, env, o, d, g, pruned, &stats);
  const auto va = a.radiance.to_vector(), vb = b.radiance.to_vector();
  double max_err = 0;
  for (size_t i = 0; i < va.size(); ++i) max_err = std::max(max_err, std::abs(va[i] - vb[i]) / std::max(1.0, va[i]));
  // Bound: min_transmittance · (1 + G_max) with G_max ≤ c ≤ softplus(1) ≈ 1.31.
  EXPECT_LT(max_err, 1e-4 * (1 + 1.32) + 1e-5);
  EXPECT_LT(stats.samples_evaluated, stats.samples_total);  // something was actually skipped
  EXPECT_GT(stats.rays_terminated, 0);
}

TEST(RadianceQuery, ResultsAndGradientsAreIdenticalWithOneAndTwoThreads) {
  const VsgGrid g = small_grid();
  Tensor vsg = random_vsg(g, 40, DType::F32);
  Tensor env = Tensor::uniform({3, 8, 16}, 0, 3, 41);
  const Rays r = random_rays(3000, 42, DType::F32);
  auto run = [&](int threads) {
    omp_set_num_threads(threads);
    Tensor v = vsg.clone().set_requires_grad(true), e = env.clone().set_requires_grad(true);
    const auto q = radiance_query(v, e, r.origins, r.dirs, g);
    backward(add(sum(square(q.radiance)), sum(q.transmittance)));
    auto out = q.radiance.to_vector();
    for (double x : v.grad().to_vector()) out.push_back(x);
    for (double x : e.grad().to_vector()) out.push_back(x);
    return out;
  };
  const auto one = run(1), two = run(2);
  ASSERT_EQ(one.size(), two.size());
  for (size_t i = 0; i < one.size(); ++i) ASSERT_EQ(one[i], two[i]) << i;
}

// Every lookup, spacing and pruning, at 24 samples: the options the RayMarcher tests cover.
std::vector<RadianceQueryOptions> march_options() {
  std::vector<RadianceQueryOptions> out;
  for (bool trilinear : {false, true})
    for (SampleSpacing spacing : {SampleSpacing::kMetric, SampleSpacing::kGrid})
      for (bool prune : {true, false}) {
        RadianceQueryOptions opt;
        opt.samples = 24;
        opt.trilinear = trilinear;
        opt.spacing = spacing;
        opt.prune = prune;
        out.push_back(opt);
      }
  return out;
}

// RayMarcher (one ray, off the tape) is the op's forward: the same bits for every lookup,
// spacing and pruning, a zero direction included.
TEST(RayMarcher, EqualsTheQueryBitForBit) {
  VsgGrid g;
  g.dims = {16, 16, 8};
  const Tensor vsg = random_vsg(g, 50, DType::F32, 0.0, 0.9);
  Tensor env = Tensor::uniform({3, 16, 32}, 0, 2, 51);
  env.data<float>()[5 * 32 + 7] = 1e5f;  // a sun, so some rays stop on transmittance
  Tensor o = Tensor::uniform({500, 3}, -20, 20, 52), d = Tensor::uniform({500, 3}, -1, 1, 53);
  slice(d, 0, 0, 1).fill_(0.0);  // a zero direction
  for (const RadianceQueryOptions& opt : march_options()) {
    const auto q = radiance_query(vsg, env, o, d, g, opt);
    const sl::render::RayMarcher march(vsg, env, g, opt);
    const float* po = o.data<float>();
    const float* pd = d.data<float>();
    for (int64_t r = 0; r < 500; ++r) {
      const auto m = march(po + 3 * r, pd + 3 * r);
      for (int c = 0; c < 3; ++c) ASSERT_EQ(m.radiance[c], q.radiance.data<float>()[3 * r + c]) << r;
      ASSERT_EQ(m.transmittance, q.transmittance.data<float>()[r]) << r;
    }
  }
}

// RayMarcher's batch (16 rays in vector lanes on AVX-512) is one ray at a time, bit for bit:
// every lookup, spacing and pruning, with rays that stop on transmittance, rays that miss the
// grid, a zero direction and a batch that is not a multiple of 16.
TEST(RayMarcher, BatchEqualsOneRayAtATime) {
  VsgGrid g;
  g.dims = {16, 16, 8};
  const Tensor vsg = random_vsg(g, 60, DType::F32, 0.0, 0.9);
  Tensor env = Tensor::uniform({3, 16, 32}, 0, 2, 61);
  env.data<float>()[5 * 32 + 7] = 1e5f;
  const int64_t n = 517;
  Tensor o = Tensor::uniform({n, 3}, -20, 20, 62), d = Tensor::uniform({n, 3}, -1, 1, 63);
  slice(d, 0, 0, 1).fill_(0.0);
  slice(o, 0, 1, 2).fill_(1e4);  // far outside the grid
  for (const RadianceQueryOptions& opt : march_options()) {
    const sl::render::RayMarcher march(vsg, env, g, opt);
    std::vector<sl::render::RayMarcher::Result> batch(static_cast<size_t>(n));
    march(n, o.data<float>(), d.data<float>(), batch.data());
    for (int64_t r = 0; r < n; ++r) {
      const auto one = march(o.data<float>() + 3 * r, d.data<float>() + 3 * r);
      for (int c = 0; c < 3; ++c) ASSERT_EQ(batch[size_t(r)].radiance[c], one.radiance[c]) << r;
      ASSERT_EQ(batch[size_t(r)].transmittance, one.transmittance) << r;
    }
  }
}

// nearest_voxels (AVX-512 lanes where compiled, else the scalar loop) is the scalar loop, index
// for index: every K around the lane width, coordinates inside, on and outside the grid's faces,
// far outside it, and -0. (NaN and ±∞ are left out: int64_t() of them is undefined in C++, though
// both paths give the hardware's 0x8000000000000000 and then 0.)
TEST(NearestVoxels, LanesEqualTheScalarLoop) {
  const int64_t dims[3] = {64, 64, 16};
  const std::vector<double> u = Tensor::uniform({3 * 40}, -6.0, 70.0, 71).to_vector();
  const float edges[] = {-0.0f, 0.0f, -1e-7f, 0.999999f, 1.0f, 15.0f, 15.99999f, 16.0f, 63.0f, 63.99999f, 64.0f,
                         64.5f, -1e6f, 1e6f, -1e12f, 1e12f};
  for (int K : {1, 7, 8, 9, 16, 31, 32, 33, 40}) {
    std::vector<float> v(size_t(3 * K));
    for (size_t i = 0; i < v.size(); ++i) v[i] = i % 5 == 4 ? edges[(i / 5) % std::size(edges)] : float(u[i]);
    std::vector<int64_t> lanes(static_cast<size_t>(K)), scalar(static_cast<size_t>(K));
    sl::render::detail::nearest_voxels(v.data(), K, dims, lanes.data());
    sl::render::detail::nearest_voxels_scalar(v.data(), K, dims, scalar.data());
    for (int k = 0; k < K; ++k) ASSERT_EQ(lanes[size_t(k)], scalar[size_t(k)]) << "K " << K << " sample " << k;
  }
}

TEST(RadianceQuery, ExtremeLobeSharpnessAndZeroAxesStayFinite) {
  const VsgGrid g = small_grid();
  for (double sharp : {1e-3, 1.0, 1e4, 1e6}) {
    Tensor vsg = random_vsg(g, 50, DType::F32);
    slice(vsg, 0, 6, 7).fill_(sharp);
    slice(vsg, 0, 3, 4).fill_(0.0);  // half the axes are zero vectors
    slice(vsg, 0, 4, 6).fill_(0.0);
    Tensor v = vsg.set_requires_grad(true);
    Tensor env = Tensor::full({3, 8, 16}, 1e6f).set_requires_grad(true);
    const Rays r = random_rays(200, 51, DType::F32);
    const auto q = radiance_query(v, env, r.origins, r.dirs, g);
    backward(sum(q.radiance));
    for (double x : q.radiance.to_vector()) ASSERT_TRUE(std::isfinite(x)) << sharp;
    for (double x : v.grad().to_vector()) ASSERT_TRUE(std::isfinite(x)) << sharp;
    for (double x : env.grad().to_vector()) ASSERT_TRUE(std::isfinite(x)) << sharp;
  }
}

TEST(RadianceQuery, BatchedQueryEqualsPerItemQueries) {
  const VsgGrid g = small_grid();
  Tensor v0 = random_vsg(g, 60, DType::F64), v1 = random_vsg(g, 61, DType::F64);
  Tensor e0 = Tensor::uniform({3, 4, 8}, 0, 1, 62, DType::F64), e1 = Tensor::uniform({3, 4, 8}, 0, 1, 63, DType::F64);
  const Rays r0 = random_rays(7, 64, DType::F64), r1 = random_rays(7, 66, DType::F64);
  const auto b = radiance_query(stack({v0, v1}, 0), stack({e0, e1}, 0), stack({r0.origins, r1.origins}, 0),
                                stack({r0.dirs, r1.dirs}, 0), g);
  const auto a1 = radiance_query(v1, e1, r1.origins, r1.dirs, g);
  EXPECT_EQ(select(b.radiance, 0, 1).to_vector(), a1.radiance.to_vector());
}

TEST(RadianceQuery, BadShapesAreErrorsNamingTheInput) {
  const VsgGrid g = small_grid();
  EXPECT_THROW(radiance_query(Tensor::zeros({7, 4, 4, 2}), Tensor::zeros({3, 4, 8}), Tensor::zeros({2, 3}),
                              Tensor::zeros({2, 3}), g),
               Error);
  EXPECT_THROW(radiance_query(Tensor::zeros({8, 4, 4, 3}), Tensor::zeros({3, 4, 8}), Tensor::zeros({2, 3}),
                              Tensor::zeros({2, 3}), g),
               Error);
}

}  // namespace
}  // namespace sl::test
