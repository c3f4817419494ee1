// Bvh queries: 8-wide box tests, blocks of watertight ray-triangle tests, ordered traversal.
// Compiled with -ffp-contract=off (render/CMakeLists.txt): the triangle test must round each
// edge function the same way for both triangles of a shared edge, in every lane.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "render/bvh.h"
#include "util/error.h"

#if defined(__AVX2__)
#include <immintrin.h>
#endif

namespace sl::render {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

#if defined(__GNUC__)
#define SL_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define SL_ALWAYS_INLINE inline
#endif

// ---------------------------------------------------------------- ray set-up (Woop et al. 2013)

// Box exits are computed with 1/d times 1 + 2γ₄, γₙ = nε/(1 - nε), ε = 2⁻²⁴: pbrt-v3 §3.9.2
// (Bounds3::IntersectP) scales the exit by 1 + 2γ₃ after the fact; folding the scale into 1/d takes
// it off each node test's critical path, and γ₄ covers the one more rounding of (1/d)·scale.
constexpr float kFarScale = 1.0f + 2.0f * (4.0f * 0x1p-24f) / (1.0f - 4.0f * 0x1p-24f);

struct PreparedRay {
  float o[3];          // origin
  float inv[3];        // 1 / direction (±∞ for a zero component)
  float inv_far[3];    // inv · kFarScale, for box exits
  // Byte offsets in BvhNode of the row holding each axis' entry plane, lo (row k) or hi (row
  // 3 + k), and of its exit plane. Pointer-sized, so a node test adds them to the node's address
  // as they are: as int rows, GCC kept them packed in vector registers and extracted, widened and
  // scaled all six at every node.
  ptrdiff_t near_off[3];
  ptrdiff_t far_off[3];
  float ox, oy, oz;    // origin permuted to (kx, ky, kz)
  float sx, sy, sz;    // shear constants, Sec. 3 of the paper
  int kx, ky, kz;
  float tmin;
  bool valid;
};

inline void shear(PreparedRay& r, const Ray& ray);

// The box-test part of the set-up; shear() adds the triangle test's part.
inline PreparedRay prepare_boxes(const Ray& ray) {
  PreparedRay r{};
  const float d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  r.o[0] = ray.origin.x, r.o[1] = ray.origin.y, r.o[2] = ray.origin.z;
  const float ad[3] = {std::fabs(d[0]), std::fabs(d[1]), std::fabs(d[2])};
  r.valid = std::isfinite(d[0]) && std::isfinite(d[1]) && std::isfinite(d[2]) &&
            std::isfinite(r.o[0] + r.o[1] + r.o[2]) && (ad[0] > 0 || ad[1] > 0 || ad[2] > 0) &&
            !std::isnan(ray.tmin) && !std::isnan(ray.tmax);
  if (!r.valid) return r;
  // 1/d first: the box tests need only it, so they need not wait for the axis choice (shear).
#if defined(__AVX2__)
  alignas(16) float q[4];
  _mm_store_ps(q, _mm_div_ps(_mm_set1_ps(1.0f), _mm_setr_ps(d[0], d[1], d[2], 1.0f)));
  r.inv[0] = q[0], r.inv[1] = q[1], r.inv[2] = q[2];
#else
  for (int k = 0; k < 3; ++k) r.inv[k] = 1.0f / d[k];
#endif
  for (int k = 0; k < 3; ++k) r.inv_far[k] = r.inv[k] * kFarScale;
  for (int k = 0; k < 3; ++k) {
    const ptrdiff_t lo = static_cast<ptrdiff_t>(offsetof(BvhNode, bounds) + k * sizeof(BvhNode::bounds[0]));
    const ptrdiff_t hi = lo + static_cast<ptrdiff_t>(3 * sizeof(BvhNode::bounds[0]));
    r.near_off[k] = std::signbit(r.inv[k]) ? hi : lo;
    r.far_off[k] = std::signbit(r.inv[k]) ? lo : hi;
  }
  // The segment starts at the origin at the earliest (Embree's rule too): a box exit behind the
  // origin would be narrowed, not widened, by kFarScale, so t < 0 is never searched.
  r.tmin = ray.tmin > 0.0f ? ray.tmin : 0.0f;
  return r;
}

// Axis permutation and shear of the watertight triangle test. Traversal calls it at the first
// leaf only: most rays of a scene that does not fill their view never reach one.
inline void shear(PreparedRay& r, const Ray& ray) {
  const float d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  const float ad[3] = {std::fabs(d[0]), std::fabs(d[1]), std::fabs(d[2])};
  // kz: the dominant axis; swapping kx and ky when d[kz] < 0 keeps the winding (paper, Fig. 2).
  // Integer arithmetic on comparison results and a table: random directions would mispredict
  // branches, and compilers turn the equivalent ternaries on indexed floats into branches.
  const int k01 = static_cast<int>(!(ad[0] > ad[1]));  // ad[k01] = max(ad[0], ad[1])
  r.kz = k01 + static_cast<int>(!(std::max(ad[0], ad[1]) > ad[2])) * (2 - k01);
  static constexpr int8_t kAxes[3][2][2] = {{{1, 2}, {2, 1}}, {{2, 0}, {0, 2}}, {{0, 1}, {1, 0}}};  // [kz][flip]
  const int flip = static_cast<int>(d[r.kz] < 0.0f);
  r.kx = kAxes[r.kz][flip][0];
  r.ky = kAxes[r.kz][flip][1];
  r.sx = d[r.kx] / d[r.kz];
  r.sy = d[r.ky] / d[r.kz];
  r.sz = r.inv[r.kz];
  r.ox = r.o[r.kx], r.oy = r.o[r.ky], r.oz = r.o[r.kz];
}

inline PreparedRay prepare(const Ray& ray) {
  PreparedRay r = prepare_boxes(ray);
  if (r.valid) shear(r, ray);
  return r;
}

// The bounds row of node n at byte offset `off` (PreparedRay::near_off, far_off).
inline const float* row(const BvhNode& n, ptrdiff_t off) {
  return reinterpret_cast<const float*>(reinterpret_cast<const char*>(&n) + off);
}

// ---------------------------------------------------------------- scalar ray-triangle test

struct Triangle {
  float p0[3], p1[3], p2[3];
};

// Returns true and sets t, u, v when the ray hits the triangle with tmin < t < tmax. The vector
// test below performs these same operations lane by lane.
inline bool hit_triangle(const PreparedRay& r, const Triangle& tri, float tmax, float& t, float& u, float& v) {
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  // Vertices relative to the origin, sheared so the ray becomes the +z axis (paper Eq. 3-4).
  const float az = tri.p0[kz] - r.oz, bz = tri.p1[kz] - r.oz, cz = tri.p2[kz] - r.oz;
  const float ax = (tri.p0[kx] - r.ox) - r.sx * az, ay = (tri.p0[ky] - r.oy) - r.sy * az;
  const float bx = (tri.p1[kx] - r.ox) - r.sx * bz, by = (tri.p1[ky] - r.oy) - r.sy * bz;
  const float cx = (tri.p2[kx] - r.ox) - r.sx * cz, cy = (tri.p2[ky] - r.oy) - r.sy * cz;
  // 2D edge functions (scaled barycentrics of p0, p1, p2).
  float e0 = cx * by - cy * bx;
  float e1 = ax * cy - ay * cx;
  float e2 = bx * ay - by * ax;
  if (e0 == 0.0f || e1 == 0.0f || e2 == 0.0f) {
    // An exact zero may be a rounding artefact on a shared edge: decide it in double (paper Sec. 4).
    e0 = static_cast<float>(static_cast<double>(cx) * by - static_cast<double>(cy) * bx);
    e1 = static_cast<float>(static_cast<double>(ax) * cy - static_cast<double>(ay) * cx);
    e2 = static_cast<float>(static_cast<double>(bx) * ay - static_cast<double>(by) * ax);
  }
  if ((e0 < 0.0f || e1 < 0.0f || e2 < 0.0f) && (e0 > 0.0f || e1 > 0.0f || e2 > 0.0f)) return false;
  const float det = e0 + e1 + e2;
  if (det == 0.0f) return false;  // degenerate, or the ray lies in the triangle's plane
  const float scaled_t = r.sz * (e0 * az + e1 * bz + e2 * cz);
  const float inv_det = 1.0f / det;
  const float th = scaled_t * inv_det;
  if (!(th > r.tmin && th < tmax)) return false;
  t = th;
  u = e1 * inv_det;
  v = e2 * inv_det;
  return true;
}

constexpr int kW = BvhNode::kWidth;
constexpr int kB = Bvh::kBlockWidth;

// Per-lane results of one triangle block; the closest hit is picked from these.
struct BlockHits {
  alignas(32) float t[kB], e1[kB], e2[kB], inv_det[kB];
};

struct StackEntry {
  uint32_t ref;
  float tnear;  // entry distance of its box
};

// Pushes the children in `mask` (two or more) so that the nearer pop first, and returns the
// nearest, which is visited next. On equal entry distances two children visit the lower slot
// first, three or more the higher (the insertion sort is stable): every kernel keeps this order,
// since it decides which of two triangles at exactly the same t is reported.
inline uint32_t defer_all_but_nearest(const BvhNode& n, unsigned mask, const float* tnear, StackEntry* stack,
                                      int& sp) {
  const int first = __builtin_ctz(mask);
  mask &= mask - 1;
  const int second = __builtin_ctz(mask);
  mask &= mask - 1;
  if (!mask) {
    const bool swap = tnear[second] < tnear[first];
    const int near = swap ? second : first, far = swap ? first : second;
    stack[sp++] = {n.child[far], tnear[far]};
    return n.child[near];
  }
  StackEntry* base = stack + sp;
  int count = 0;
  base[count++] = {n.child[first], tnear[first]};
  base[count++] = {n.child[second], tnear[second]};
  for (; mask; mask &= mask - 1) {
    const int i = __builtin_ctz(mask);
    base[count++] = {n.child[i], tnear[i]};
  }
  for (int i = 1; i < count; ++i) {  // insertion sort, farthest at the bottom
    const StackEntry e = base[i];
    int j = i;
    for (; j > 0 && base[j - 1].tnear < e.tnear; --j) base[j] = base[j - 1];
    base[j] = e;
  }
  sp += count - 1;
  return base[count - 1].ref;
}

// Two sets of box and triangle tests, each in its namespace with its own SimdRay, so the
// traversal below picks a set by the SimdRay type it is instantiated with (overloads found
// through the argument's namespace): AVX2 intrinsics when compiled for AVX2, and portable lane
// loops, always compiled, which Bvh::use_portable_kernels selects at run time.
#if defined(__AVX2__)
// ---------------------------------------------------------------- vector tests
namespace avx2 {

static_assert(kW == 8 && kB == 8, "the vector tests below are written for 8 lanes");

struct SimdRay {
#if defined(__AVX512F__) && defined(__AVX512VL__)
  static constexpr bool kPairs = true;  // hit_block_pair below
#else
  static constexpr bool kPairs = false;
#endif
  __m256 o[3], inv[3], inv_far[3], tmin;
  __m256 sx, sy, sz;

  explicit SimdRay(const PreparedRay& r) {
    for (int k = 0; k < 3; ++k) {
      o[k] = _mm256_set1_ps(r.o[k]), inv[k] = _mm256_set1_ps(r.inv[k]), inv_far[k] = _mm256_set1_ps(r.inv_far[k]);
    }
    tmin = _mm256_set1_ps(r.tmin);
  }
  void set_shear(const PreparedRay& r) {
    sx = _mm256_set1_ps(r.sx), sy = _mm256_set1_ps(r.sy), sz = _mm256_set1_ps(r.sz);
  }
};

// Slab test of all children. Returns the mask of children whose [tnear, tfar] meets
// [tmin, tmax] and stores their entry distances. A zero direction component gives 0·∞ = NaN
// when the origin lies on that slab's plane; max/min return their second operand when the
// first is NaN, so a NaN entry acts as −∞ and a NaN exit as +∞ (that slab does not limit the ray).
inline unsigned hit_children(const BvhNode& n, const PreparedRay& r, const SimdRay& s, float tmax, float* tnear) {
  __m256 near = s.tmin, far = _mm256_set1_ps(kInf);
  for (int k = 0; k < 3; ++k) {
    const __m256 tn = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(row(n, r.near_off[k])), s.o[k]), s.inv[k]);
    const __m256 tf = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(row(n, r.far_off[k])), s.o[k]), s.inv_far[k]);
    near = _mm256_max_ps(tn, near);
    far = _mm256_min_ps(tf, far);
  }
  far = _mm256_min_ps(far, _mm256_set1_ps(tmax));
  _mm256_store_ps(tnear, near);
  return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(near, far, _CMP_LE_OQ)));
}

// a·b − c·d per lane with float inputs, computed in double and rounded to float once.
inline __m256 edge_in_double(__m256 a, __m256 b, __m256 c, __m256 d) {
  auto half = [](__m128 a, __m128 b, __m128 c, __m128 d) {
    return _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_mul_pd(_mm256_cvtps_pd(a), _mm256_cvtps_pd(b)),
                                         _mm256_mul_pd(_mm256_cvtps_pd(c), _mm256_cvtps_pd(d))));
  };
  const __m128 lo = half(_mm256_castps256_ps128(a), _mm256_castps256_ps128(b), _mm256_castps256_ps128(c),
                         _mm256_castps256_ps128(d));
  const __m128 hi = half(_mm256_extractf128_ps(a, 1), _mm256_extractf128_ps(b, 1), _mm256_extractf128_ps(c, 1),
                         _mm256_extractf128_ps(d, 1));
  return _mm256_set_m128(hi, lo);
}

// Tests the lanes in `lanes` of one block. Returns the mask of lanes hit with tmin < t < tmax.
inline unsigned hit_block(const Bvh::TriangleBlock& b, const PreparedRay& r, const SimdRay& s, float tmax,
                          unsigned lanes, BlockHits& out) {
  const __m256 zero = _mm256_setzero_ps();
  auto at = [&](int vertex, int axis) { return _mm256_load_ps(b.v[vertex][axis]); };
  const __m256 ox = s.o[r.kx], oy = s.o[r.ky], oz = s.o[r.kz];
  const __m256 az = _mm256_sub_ps(at(0, r.kz), oz), bz = _mm256_sub_ps(at(1, r.kz), oz),
               cz = _mm256_sub_ps(at(2, r.kz), oz);
  const __m256 ax = _mm256_sub_ps(_mm256_sub_ps(at(0, r.kx), ox), _mm256_mul_ps(s.sx, az));
  const __m256 ay = _mm256_sub_ps(_mm256_sub_ps(at(0, r.ky), oy), _mm256_mul_ps(s.sy, az));
  const __m256 bx = _mm256_sub_ps(_mm256_sub_ps(at(1, r.kx), ox), _mm256_mul_ps(s.sx, bz));
  const __m256 by = _mm256_sub_ps(_mm256_sub_ps(at(1, r.ky), oy), _mm256_mul_ps(s.sy, bz));
  const __m256 cx = _mm256_sub_ps(_mm256_sub_ps(at(2, r.kx), ox), _mm256_mul_ps(s.sx, cz));
  const __m256 cy = _mm256_sub_ps(_mm256_sub_ps(at(2, r.ky), oy), _mm256_mul_ps(s.sy, cz));
  __m256 e0 = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
  __m256 e1 = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
  __m256 e2 = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
  const __m256 has_zero = _mm256_or_ps(_mm256_or_ps(_mm256_cmp_ps(e0, zero, _CMP_EQ_OQ), _mm256_cmp_ps(e1, zero, _CMP_EQ_OQ)),
                                       _mm256_cmp_ps(e2, zero, _CMP_EQ_OQ));
  if (_mm256_movemask_ps(has_zero) & lanes) {
    // Exact zeros may be rounding artefacts on a shared edge: decide those lanes in double
    // (float products are exact in double), as the scalar test does.
    e0 = _mm256_blendv_ps(e0, edge_in_double(cx, by, cy, bx), has_zero);
    e1 = _mm256_blendv_ps(e1, edge_in_double(ax, cy, ay, cx), has_zero);
    e2 = _mm256_blendv_ps(e2, edge_in_double(bx, ay, by, ax), has_zero);
  }
  const __m256 any_neg = _mm256_or_ps(_mm256_or_ps(_mm256_cmp_ps(e0, zero, _CMP_LT_OQ), _mm256_cmp_ps(e1, zero, _CMP_LT_OQ)),
                                      _mm256_cmp_ps(e2, zero, _CMP_LT_OQ));
  const __m256 any_pos = _mm256_or_ps(_mm256_or_ps(_mm256_cmp_ps(e0, zero, _CMP_GT_OQ), _mm256_cmp_ps(e1, zero, _CMP_GT_OQ)),
                                      _mm256_cmp_ps(e2, zero, _CMP_GT_OQ));
  const __m256 mixed = _mm256_and_ps(any_neg, any_pos);
  // No lane inside all three edges: stop before the division (a 256-bit divide issues at most
  // every 5 cycles on Golden Cove) and the t test; the result is the same.
  if (!(~static_cast<unsigned>(_mm256_movemask_ps(mixed)) & lanes)) return 0;
  const __m256 det = _mm256_add_ps(_mm256_add_ps(e0, e1), e2);
  const __m256 scaled_t = _mm256_mul_ps(
      s.sz, _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(e0, az), _mm256_mul_ps(e1, bz)), _mm256_mul_ps(e2, cz)));
  const __m256 inv_det = _mm256_div_ps(_mm256_set1_ps(1.0f), det);
  const __m256 t = _mm256_mul_ps(scaled_t, inv_det);
  __m256 ok = _mm256_andnot_ps(mixed, _mm256_cmp_ps(det, zero, _CMP_NEQ_OQ));
  ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(t, s.tmin, _CMP_GT_OQ),
                                       _mm256_cmp_ps(t, _mm256_set1_ps(tmax), _CMP_LT_OQ)));
  const unsigned mask = static_cast<unsigned>(_mm256_movemask_ps(ok)) & lanes;
  if (mask) {
    _mm256_store_ps(out.t, t), _mm256_store_ps(out.e1, e1), _mm256_store_ps(out.e2, e2);
    _mm256_store_ps(out.inv_det, inv_det);
  }
  return mask;
}

#if defined(__AVX512F__) && defined(__AVX512VL__)
// Per-lane results of two consecutive triangle blocks tested together.
struct PairHits {
  alignas(64) float t[2 * kB], e1[2 * kB], e2[2 * kB], inv_det[2 * kB];
};

// Lanes 0-7 from lo, 8-15 from hi. Masked inserts with all lanes set: GCC 12's unmasked ones
// (and the zero extensions built on them) start from an undefined vector and warn about it.
inline __m512 join(__m256 lo, __m256 hi) {
  const __m512d low = _mm512_maskz_insertf64x4(0xFF, _mm512_setzero_pd(), _mm256_castps_pd(lo), 0);
  return _mm512_castpd_ps(_mm512_mask_insertf64x4(low, 0xFF, low, _mm256_castps_pd(hi), 1));
}

// hit_block on blocks b[0] and b[1] at once, lane l of b[1] being lane 8 + l: the same IEEE
// operations per lane in 16-wide vectors, so a leaf that spans two blocks (a leaf starts at any
// lane) is one pass instead of two dependent ones. `lanes` has 16 bits.
inline unsigned hit_block_pair(const Bvh::TriangleBlock* b, const PreparedRay& r, float tmax, unsigned lanes,
                               PairHits& out) {
  const __m512 zero = _mm512_setzero_ps();
  auto at = [&](int vertex, int axis) { return join(_mm256_load_ps(b[0].v[vertex][axis]), _mm256_load_ps(b[1].v[vertex][axis])); };
  const __m512 ox = _mm512_set1_ps(r.ox), oy = _mm512_set1_ps(r.oy), oz = _mm512_set1_ps(r.oz);
  const __m512 sx = _mm512_set1_ps(r.sx), sy = _mm512_set1_ps(r.sy);
  const __m512 az = _mm512_sub_ps(at(0, r.kz), oz), bz = _mm512_sub_ps(at(1, r.kz), oz),
               cz = _mm512_sub_ps(at(2, r.kz), oz);
  const __m512 ax = _mm512_sub_ps(_mm512_sub_ps(at(0, r.kx), ox), _mm512_mul_ps(sx, az));
  const __m512 ay = _mm512_sub_ps(_mm512_sub_ps(at(0, r.ky), oy), _mm512_mul_ps(sy, az));
  const __m512 bx = _mm512_sub_ps(_mm512_sub_ps(at(1, r.kx), ox), _mm512_mul_ps(sx, bz));
  const __m512 by = _mm512_sub_ps(_mm512_sub_ps(at(1, r.ky), oy), _mm512_mul_ps(sy, bz));
  const __m512 cx = _mm512_sub_ps(_mm512_sub_ps(at(2, r.kx), ox), _mm512_mul_ps(sx, cz));
  const __m512 cy = _mm512_sub_ps(_mm512_sub_ps(at(2, r.ky), oy), _mm512_mul_ps(sy, cz));
  __m512 e0 = _mm512_sub_ps(_mm512_mul_ps(cx, by), _mm512_mul_ps(cy, bx));
  __m512 e1 = _mm512_sub_ps(_mm512_mul_ps(ax, cy), _mm512_mul_ps(ay, cx));
  __m512 e2 = _mm512_sub_ps(_mm512_mul_ps(bx, ay), _mm512_mul_ps(by, ax));
  const __mmask16 has_zero = static_cast<__mmask16>(_mm512_cmp_ps_mask(e0, zero, _CMP_EQ_OQ) |
                                                    _mm512_cmp_ps_mask(e1, zero, _CMP_EQ_OQ) |
                                                    _mm512_cmp_ps_mask(e2, zero, _CMP_EQ_OQ));
  if (has_zero & lanes) {
    // Exact zeros: those lanes in double, as the scalar test does, one 8-lane half at a time.
    auto in_double = [](__m512 a, __m512 b, __m512 c, __m512 d) {
      auto lo = [](__m512 x) { return _mm512_castps512_ps256(x); };
      auto hi = [](__m512 x) { return _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(x), 1)); };
      const __m256 l = edge_in_double(lo(a), lo(b), lo(c), lo(d)), h = edge_in_double(hi(a), hi(b), hi(c), hi(d));
      return join(l, h);
    };
    e0 = _mm512_mask_mov_ps(e0, has_zero, in_double(cx, by, cy, bx));
    e1 = _mm512_mask_mov_ps(e1, has_zero, in_double(ax, cy, ay, cx));
    e2 = _mm512_mask_mov_ps(e2, has_zero, in_double(bx, ay, by, ax));
  }
  const __mmask16 any_neg = static_cast<__mmask16>(_mm512_cmp_ps_mask(e0, zero, _CMP_LT_OQ) |
                                                   _mm512_cmp_ps_mask(e1, zero, _CMP_LT_OQ) |
                                                   _mm512_cmp_ps_mask(e2, zero, _CMP_LT_OQ));
  const __mmask16 any_pos = static_cast<__mmask16>(_mm512_cmp_ps_mask(e0, zero, _CMP_GT_OQ) |
                                                   _mm512_cmp_ps_mask(e1, zero, _CMP_GT_OQ) |
                                                   _mm512_cmp_ps_mask(e2, zero, _CMP_GT_OQ));
  const unsigned inside = ~static_cast<unsigned>(any_neg & any_pos) & lanes;
  if (!inside) return 0;
  const __m512 det = _mm512_add_ps(_mm512_add_ps(e0, e1), e2);
  const __m512 scaled_t = _mm512_mul_ps(_mm512_set1_ps(r.sz),
                                        _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(e0, az), _mm512_mul_ps(e1, bz)),
                                                      _mm512_mul_ps(e2, cz)));
  const __m512 inv_det = _mm512_div_ps(_mm512_set1_ps(1.0f), det);
  const __m512 t = _mm512_mul_ps(scaled_t, inv_det);
  const unsigned mask = inside & _mm512_cmp_ps_mask(det, zero, _CMP_NEQ_OQ) &
                        _mm512_cmp_ps_mask(t, _mm512_set1_ps(r.tmin), _CMP_GT_OQ) &
                        _mm512_cmp_ps_mask(t, _mm512_set1_ps(tmax), _CMP_LT_OQ);
  if (mask) {
    _mm512_store_ps(out.t, t), _mm512_store_ps(out.e1, e1), _mm512_store_ps(out.e2, e2);
    _mm512_store_ps(out.inv_det, inv_det);
  }
  return mask;
}

// Three or more children, in the order of defer_all_but_nearest without its branches: 64-bit
// keys (entry distance as an ordered integer, then 7 − slot) go through an 8-key bitonic network,
// and the nearest comes from a separate float min over the entry distances, so that the next
// node's load does not wait for the network. A key's slot picks its stack entry with one permute.
constexpr __mmask8 keeps_larger(int k, int j) {  // network step (k, j), sorting in descending order
  unsigned m = 0;
  for (int i = 0; i < 8; ++i) m |= static_cast<unsigned>(((i & k) == 0) != ((i & j) != 0)) << i;
  return static_cast<__mmask8>(m);
}
template <int k, int j>
SL_ALWAYS_INLINE __m512i sort_step(__m512i v) {
  __m512i partner;  // lane i ^ j
  if constexpr (j == 1) partner = _mm512_shuffle_epi32(v, _MM_PERM_BADC);
  if constexpr (j == 2) partner = _mm512_permutex_epi64(v, _MM_SHUFFLE(1, 0, 3, 2));
  if constexpr (j == 4) partner = _mm512_shuffle_i64x2(v, v, _MM_SHUFFLE(1, 0, 3, 2));
  return _mm512_mask_blend_epi64(keeps_larger(k, j), _mm512_min_epi64(v, partner), _mm512_max_epi64(v, partner));
}

inline uint32_t defer_all_but_nearest(const BvhNode& n, unsigned mask, const float* tnear, StackEntry* stack, int& sp,
                                      const SimdRay&) {
  const unsigned rest = mask & (mask - 1);
  if (!(rest & (rest - 1))) return render::defer_all_but_nearest(n, mask, tnear, stack, sp);  // two: one compare
  const __m256 t = _mm256_load_ps(tnear);
  // +0 for −0, which the float comparisons tie with +0; then negative floats flipped to order as integers.
  const __m256i bits = _mm256_castps_si256(_mm256_add_ps(t, _mm256_setzero_ps()));
  const __m256i ordered = _mm256_xor_si256(bits, _mm256_srli_epi32(_mm256_srai_epi32(bits, 31), 1));
  const __m512i key = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepi32_epi64(ordered), 32),
                                      _mm512_setr_epi64(7, 6, 5, 4, 3, 2, 1, 0));
  const __mmask8 hit = static_cast<__mmask8>(mask);
  // The nearest: the least entry distance of the entered children, the highest slot among equal
  // ones (−0 and +0 compare equal), which is the least key; three min steps on floats are fewer
  // than the 64-bit reduction's before the next node's load can start.
  __m256 m = _mm256_mask_blend_ps(hit, _mm256_set1_ps(kInf), t);
  m = _mm256_min_ps(m, _mm256_permute_ps(m, _MM_SHUFFLE(2, 3, 0, 1)));
  m = _mm256_min_ps(m, _mm256_permute_ps(m, _MM_SHUFFLE(1, 0, 3, 2)));
  m = _mm256_min_ps(m, _mm256_permute2f128_ps(m, m, 1));
  const unsigned ties = _mm256_mask_cmp_ps_mask(hit, t, m, _CMP_EQ_OQ);
  const int nearest_slot = 31 - __builtin_clz(ties);
  __m512i v = _mm512_mask_mov_epi64(_mm512_set1_epi64(INT64_MIN), hit, key);  // missed children last
  v = sort_step<2, 1>(v), v = sort_step<4, 2>(v), v = sort_step<4, 1>(v);
  v = sort_step<8, 4>(v), v = sort_step<8, 2>(v), v = sort_step<8, 1>(v);
  // Stack entries {ref, tnear} as 64-bit lanes; permutexvar reads the slot (7 − key's low bits).
  const __m512i entries =
      _mm512_or_si512(_mm512_cvtepu32_epi64(_mm256_load_si256(reinterpret_cast<const __m256i*>(n.child))),
                      _mm512_slli_epi64(_mm512_cvtepu32_epi64(_mm256_castps_si256(t)), 32));
  static_assert(sizeof(StackEntry) == 8 && offsetof(StackEntry, tnear) == 4);
  _mm512_storeu_si512(stack + sp, _mm512_permutexvar_epi64(_mm512_xor_si512(v, _mm512_set1_epi64(7)), entries));
  sp += __builtin_popcount(mask) - 1;  // the farthest first; the nearest, on top, is overwritten later
  return n.child[nearest_slot];
}
#else
inline uint32_t defer_all_but_nearest(const BvhNode& n, unsigned mask, const float* tnear, StackEntry* stack, int& sp,
                                      const SimdRay&) {
  return render::defer_all_but_nearest(n, mask, tnear, stack, sp);
}
#endif

}  // namespace avx2
#endif

// ---------------------------------------------------------------- portable fallback
namespace portable {

struct SimdRay {
  static constexpr bool kPairs = false;
  explicit SimdRay(const PreparedRay&) {}
  void set_shear(const PreparedRay&) {}
};

// The same tests as lane loops without branches, which compilers vectorise for SSE.
inline unsigned hit_children(const BvhNode& n, const PreparedRay& r, const SimdRay&, float tmax, float* tnear) {
  float far[kW];
  for (int i = 0; i < kW; ++i) tnear[i] = r.tmin, far[i] = kInf;
  for (int k = 0; k < 3; ++k) {
    const float* lo = row(n, r.near_off[k]);
    const float* hi = row(n, r.far_off[k]);
    for (int i = 0; i < kW; ++i) {
      const float tn = (lo[i] - r.o[k]) * r.inv[k], tf = (hi[i] - r.o[k]) * r.inv_far[k];
      tnear[i] = tnear[i] < tn ? tn : tnear[i];  // NaN entry: keeps tnear
      far[i] = tf < far[i] ? tf : far[i];        // NaN exit: keeps far
    }
  }
  unsigned mask = 0;
  for (int i = 0; i < kW; ++i) {
    const float limit = far[i] < tmax ? far[i] : tmax;
    mask |= static_cast<unsigned>(tnear[i] <= limit) << i;
  }
  return mask;
}

inline unsigned hit_block(const Bvh::TriangleBlock& b, const PreparedRay& r, const SimdRay&, float tmax,
                          unsigned lanes, BlockHits& out) {
  float az[kB], bz[kB], cz[kB], ax[kB], ay[kB], bx[kB], by[kB], cx[kB], cy[kB];
  unsigned has_zero = 0;
  for (int l = 0; l < kB; ++l) {
    az[l] = b.v[0][r.kz][l] - r.oz, bz[l] = b.v[1][r.kz][l] - r.oz, cz[l] = b.v[2][r.kz][l] - r.oz;
    ax[l] = (b.v[0][r.kx][l] - r.ox) - r.sx * az[l], ay[l] = (b.v[0][r.ky][l] - r.oy) - r.sy * az[l];
    bx[l] = (b.v[1][r.kx][l] - r.ox) - r.sx * bz[l], by[l] = (b.v[1][r.ky][l] - r.oy) - r.sy * bz[l];
    cx[l] = (b.v[2][r.kx][l] - r.ox) - r.sx * cz[l], cy[l] = (b.v[2][r.ky][l] - r.oy) - r.sy * cz[l];
    out.e1[l] = ax[l] * cy[l] - ay[l] * cx[l];
    out.e2[l] = bx[l] * ay[l] - by[l] * ax[l];
    out.t[l] = cx[l] * by[l] - cy[l] * bx[l];  // e0 until the end
    has_zero |= static_cast<unsigned>(out.t[l] == 0.0f || out.e1[l] == 0.0f || out.e2[l] == 0.0f) << l;
  }
  for (unsigned m = has_zero & lanes; m; m &= m - 1) {
    const int l = __builtin_ctz(m);  // decided in double, as in the scalar test
    out.t[l] = static_cast<float>(static_cast<double>(cx[l]) * by[l] - static_cast<double>(cy[l]) * bx[l]);
    out.e1[l] = static_cast<float>(static_cast<double>(ax[l]) * cy[l] - static_cast<double>(ay[l]) * cx[l]);
    out.e2[l] = static_cast<float>(static_cast<double>(bx[l]) * ay[l] - static_cast<double>(by[l]) * ax[l]);
  }
  unsigned mask = 0;
  for (int l = 0; l < kB; ++l) {
    const float e0 = out.t[l], e1 = out.e1[l], e2 = out.e2[l];
    const bool mixed = (e0 < 0.0f || e1 < 0.0f || e2 < 0.0f) && (e0 > 0.0f || e1 > 0.0f || e2 > 0.0f);
    const float det = e0 + e1 + e2;
    const float scaled_t = r.sz * (e0 * az[l] + e1 * bz[l] + e2 * cz[l]);
    const float inv_det = 1.0f / det;
    const float t = scaled_t * inv_det;
    out.t[l] = t, out.inv_det[l] = inv_det;
    mask |= static_cast<unsigned>(!mixed && det != 0.0f && t > r.tmin && t < tmax) << l;
  }
  return mask & lanes;
}

inline uint32_t defer_all_but_nearest(const BvhNode& n, unsigned mask, const float* tnear, StackEntry* stack, int& sp,
                                      const SimdRay&) {
  return render::defer_all_but_nearest(n, mask, tnear, stack, sp);
}

}  // namespace portable

#if defined(__AVX2__)
using BestSimdRay = avx2::SimdRay;
#else
using BestSimdRay = portable::SimdRay;
#endif

// Records the hit of a block test's lane mask (never 0): any-hit its first lane; closest-hit the
// closest lane, on equal t the first, as a one-by-one test would keep it. `base` is the first
// lane's slot (block * kBlockWidth). Hits: BlockHits or avx2::PairHits.
template <bool kAnyHit, class Hits>
SL_ALWAYS_INLINE void take_hit(unsigned mask, const Hits& h, uint32_t base, float& tmax, Hit& hit, uint32_t& slot) {
  int lane = __builtin_ctz(mask);
  if constexpr (!kAnyHit) {
    for (mask &= mask - 1; mask; mask &= mask - 1) {
      const int l = __builtin_ctz(mask);
      if (h.t[l] < h.t[lane]) lane = l;
    }
  }
  tmax = h.t[lane];
  hit.t = tmax, hit.u = h.e1[lane] * h.inv_det[lane], hit.v = h.e2[lane] * h.inv_det[lane];
  slot = base + lane;
}

// Tests the triangles of leaf `ref` (kPairs: a leaf over two blocks with hit_block_pair, when
// compiled for AVX-512). Closest-hit narrows tmax to each closer hit and records it in `hit` and
// `slot` (block * kBlockWidth + lane); any-hit returns true at the first hit.
// Always inlined: GCC 12 left it a call, before which it zeroed the upper vector halves
// (vzeroupper) and spilled the ray's vectors, to reload them inside and again after.
template <bool kAnyHit, bool kPairs, class SimdRay>
SL_ALWAYS_INLINE bool hit_leaf(const Bvh::TriangleBlock* blocks, uint32_t ref, const PreparedRay& r,
                               const SimdRay& s, float& tmax, Hit& hit, uint32_t& slot) {
  const uint32_t first = BvhNode::leaf_block(ref) * kB + BvhNode::leaf_lane(ref), end = first + BvhNode::leaf_count(ref);
  bool found = false;
  uint32_t b = first / kB;
#if defined(__AVX512F__) && defined(__AVX512VL__)
  if constexpr (kPairs && SimdRay::kPairs) {
    // Leaves over two or three blocks (leaves of 9-16 triangles): their first two blocks in one
    // 16-wide pass. The closest of its lanes, the first on equal t, is the hit the two 8-wide passes
    // in turn would give. Only in the prefetching traversal (trees larger than the L2 cache): in a
    // tree that fits, the second pass's loads hit the cache, and the 16-wide code cost the truck's
    // any-hit query 3-5% (A/B, AMD EPYC family 26).
    if ((b + 1) * kB < end) {
      const uint32_t lo = first - b * kB, hi = std::min(end, (b + 2) * kB) - b * kB;
      const unsigned lanes = ((1u << hi) - 1u) & ~((1u << lo) - 1u);
      avx2::PairHits h;
      unsigned mask = avx2::hit_block_pair(blocks + b, r, tmax, lanes, h);
      if (mask) {
        take_hit<kAnyHit>(mask, h, b * kB, tmax, hit, slot);
        found = true;
        if constexpr (kAnyHit) return true;
      }
      b += 2;
    }
  }
#endif
  for (; b * kB < end; ++b) {  // the leaf's slots [first, end), block by block
    const uint32_t lo = std::max(first, b * kB) - b * kB, hi = std::min(end, (b + 1) * kB) - b * kB;
    const unsigned lanes = ((1u << hi) - 1u) & ~((1u << lo) - 1u);
    BlockHits h;
    unsigned mask = hit_block(blocks[b], r, s, tmax, lanes, h);
    if (!mask) continue;
    take_hit<kAnyHit>(mask, h, b * kB, tmax, hit, slot);
    found = true;
    if constexpr (kAnyHit) break;
  }
  return found;
}

}  // namespace

template <bool kAnyHit, class SimdRay, bool kPrefetch>
inline Hit Bvh::traverse(const Ray& ray) const {
  Hit hit;
  if (nodes_.empty()) return hit;
  PreparedRay r = prepare_boxes(ray);
  if (!r.valid) return hit;
  SimdRay s(r);
  bool sheared = false;
  float tmax = ray.tmax;
  uint32_t slot = Hit::kNone;  // block * kBlockWidth + lane of the closest hit so far
  // Each level defers at most kWidth − 1 children; kWidth more for the vector sort's 8-lane store.
  StackEntry stack[(kW - 1) * kMaxDepth + kW];
  int sp = 0;
  uint32_t ref = 0;  // the root node
  for (;;) {
    if (!BvhNode::is_leaf(ref)) {
      const BvhNode& n = nodes_[ref];
      alignas(32) float tnear[kW];
      const unsigned mask = hit_children(n, r, s, tmax, tnear);
      if (kPrefetch && mask) {
        // Start loading every child the ray enters, so their cache misses overlap.
        for (unsigned m = mask; m; m &= m - 1) {
          const uint32_t c = n.child[__builtin_ctz(m)];
          // Leaf or node, both addresses computed and one selected (a conditional move): children of
          // both kinds mix unpredictably, and a branch on the kind mispredicts.
          // (GCC 12 compiles a plain ?: here to a branch.)
          uintptr_t p_addr = reinterpret_cast<uintptr_t>(nodes_.data()) + uintptr_t{c} * sizeof(BvhNode);
          const uintptr_t to_leaf = reinterpret_cast<uintptr_t>(blocks_.data()) +
                                    uintptr_t{BvhNode::leaf_block(c)} * sizeof(TriangleBlock);
#if defined(__x86_64__) && defined(__GNUC__)
          asm("test %[c], %[c]\n\tcmovs %[leaf], %[p]" : [p] "+r"(p_addr) : [c] "r"(c), [leaf] "r"(to_leaf) : "cc");
#else
          p_addr = BvhNode::is_leaf(c) ? to_leaf : p_addr;
#endif
          const char* p = reinterpret_cast<const char*>(p_addr);
          // Five lines cover a block or a node (4, then the next node's first): a fixed
          // count, as a loop over the size would mispredict its exit (prefetches never fault).
          static_assert(sizeof(TriangleBlock) <= 5 * 64 && sizeof(BvhNode) <= 5 * 64);
          __builtin_prefetch(p), __builtin_prefetch(p + 64), __builtin_prefetch(p + 128);
          __builtin_prefetch(p + 192), __builtin_prefetch(p + 256);
        }
      }
      if (mask) {
        if (!(mask & (mask - 1))) {
          ref = n.child[__builtin_ctz(mask)];
          continue;
        }
        if constexpr (kAnyHit) {
          // Any hit ends the search, so order does not matter.
          ref = n.child[__builtin_ctz(mask)];
          for (unsigned m = mask & (mask - 1); m; m &= m - 1) stack[sp++] = {n.child[__builtin_ctz(m)], 0.0f};
        } else {
          ref = defer_all_but_nearest(n, mask, tnear, stack, sp, s);
        }
        continue;
      }
    } else if ((sheared || (shear(r, ray), s.set_shear(r), sheared = true)) &&
               hit_leaf<kAnyHit, kPrefetch>(blocks_.data(), ref, r, s, tmax, hit, slot) && kAnyHit) {
      hit.triangle = blocks_[slot / kB].id[slot % kB];
      return hit;
    }
    // Pop the next subtree; closest-hit skips those that start beyond the closest hit.
    for (;;) {
      if (sp == 0) {
        if (slot != Hit::kNone) hit.triangle = blocks_[slot / kB].id[slot % kB];
        return hit;
      }
      const StackEntry e = stack[--sp];
      if (kAnyHit || e.tnear <= tmax) {
        ref = e.ref;
        break;
      }
    }
  }
}

template <bool kAnyHit>
Hit Bvh::dispatch(const Ray& ray) const {
  const bool prefetch = prefetch_;
  if (portable_kernels_)
    return prefetch ? traverse<kAnyHit, portable::SimdRay, true>(ray) : traverse<kAnyHit, portable::SimdRay, false>(ray);
  return prefetch ? traverse<kAnyHit, BestSimdRay, true>(ray) : traverse<kAnyHit, BestSimdRay, false>(ray);
}

Hit Bvh::intersect(const Ray& ray) const { return dispatch<false>(ray); }
bool Bvh::occluded(const Ray& ray) const { return dispatch<true>(ray).hit(); }

void Bvh::intersect(const Ray* rays, Hit* hits, size_t count) const {
  const int64_t n = static_cast<int64_t>(count);
#pragma omp parallel for schedule(dynamic, 64)
  for (int64_t i = 0; i < n; ++i) hits[i] = intersect(rays[i]);
}

void Bvh::occluded(const Ray* rays, uint8_t* occluded, size_t count) const {
  const int64_t n = static_cast<int64_t>(count);
#pragma omp parallel for schedule(dynamic, 64)
  for (int64_t i = 0; i < n; ++i) occluded[i] = this->occluded(rays[i]) ? 1 : 0;
}

Hit intersect_brute_force(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
                          const Ray& ray) {
  Hit hit;
  const PreparedRay r = prepare(ray);
  if (!r.valid) return hit;
  float tmax = ray.tmax;
  for (size_t i = 0; i < triangles.size(); ++i) {
    const glm::uvec3 t = triangles[i];
    SL_CHECK(t.x < positions.size() && t.y < positions.size() && t.z < positions.size(), "intersect_brute_force: ",
             "triangle ", i, " has a vertex index out of range [0, ", positions.size(), ")");
    const glm::vec3 p0 = positions[t.x], p1 = positions[t.y], p2 = positions[t.z];
    const Triangle tri{{p0.x, p0.y, p0.z}, {p1.x, p1.y, p1.z}, {p2.x, p2.y, p2.z}};
    float th, u, v;
    if (hit_triangle(r, tri, tmax, th, u, v)) {
      tmax = th;
      hit.t = th, hit.u = u, hit.v = v, hit.triangle = static_cast<uint32_t>(i);
    }
  }
  return hit;
}

}  // namespace sl::render
