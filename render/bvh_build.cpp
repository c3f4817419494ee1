// Bvh construction: binned SAH grown directly into an 8-wide tree, then laid out depth-first.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <cstdlib>
#include <memory>
#include <new>

#include "render/bvh.h"
#include "util/error.h"

#if defined(__SSE4_1__)
#include <immintrin.h>
#endif
#if defined(__linux__)
#include <sys/mman.h>
#endif
#include <unistd.h>

namespace sl::render {

constexpr size_t kHugePage = size_t{2} << 20;

void* bvh_allocate(size_t bytes) {
  if (bytes < kHugePage) return ::operator new(bytes, std::align_val_t{64});
  const size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = std::aligned_alloc(kHugePage, rounded);
  if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  madvise(p, rounded, MADV_HUGEPAGE);  // a hint: without huge pages it is only slower
#endif
  return p;
}

void bvh_deallocate(void* p, size_t bytes) {
  if (bytes < kHugePage)
    ::operator delete(p, std::align_val_t{64});
  else
    std::free(p);
}

namespace {

// The L2 cache of one core in bytes, as the CPU reports it (glibc reads CPUID); 256 KiB, the
// smallest of current x86-64 cores, when it is unknown.
size_t l2_cache_bytes() {
  static const size_t bytes = [] {
    long l2 = -1;
#if defined(_SC_LEVEL2_CACHE_SIZE)
    l2 = sysconf(_SC_LEVEL2_CACHE_SIZE);
#endif
    return l2 > 0 ? static_cast<size_t>(l2) : size_t{256} << 10;
  }();
  return bytes;
}

// ---------------------------------------------------------------- 4-float vectors (x, y, z, 0)

#if defined(__SSE4_1__)
struct V4 {
  __m128 m;
};
inline V4 load4(const float* p) { return {_mm_load_ps(p)}; }
inline V4 splat(float f) { return {_mm_set1_ps(f)}; }
inline V4 vmin(V4 a, V4 b) { return {_mm_min_ps(a.m, b.m)}; }
inline V4 vmax(V4 a, V4 b) { return {_mm_max_ps(a.m, b.m)}; }
inline V4 operator+(V4 a, V4 b) { return {_mm_add_ps(a.m, b.m)}; }
inline V4 operator-(V4 a, V4 b) { return {_mm_sub_ps(a.m, b.m)}; }
inline V4 operator*(V4 a, V4 b) { return {_mm_mul_ps(a.m, b.m)}; }
inline V4 drop_lane3(V4 a) { return {_mm_blend_ps(a.m, _mm_setzero_ps(), 8)}; }
inline float lane(V4 a, int k) {
  alignas(16) float f[4];
  _mm_store_ps(f, a.m);
  return f[k];
}
// Bin index per axis, clamped to [0, bins − 1]; lane 3 is ignored.
inline void bin_index(V4 c, V4 base, V4 scale, int bins, int out[4]) {
  __m128i i = _mm_cvttps_epi32(_mm_mul_ps(_mm_sub_ps(c.m, base.m), scale.m));
  i = _mm_max_epi32(_mm_min_epi32(i, _mm_set1_epi32(bins - 1)), _mm_setzero_si128());
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out), i);
}
// Half the surface area of the box [lo, hi] (0 when empty); lane 3 is ignored.
inline float half_area(V4 lo, V4 hi) {
  const __m128 e = _mm_max_ps(_mm_sub_ps(hi.m, lo.m), _mm_setzero_ps());
  const __m128 p = _mm_mul_ps(e, _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 0, 2, 1)));  // xy, yz, zx
  return _mm_cvtss_f32(p) + _mm_cvtss_f32(_mm_shuffle_ps(p, p, 1)) + _mm_cvtss_f32(_mm_shuffle_ps(p, p, 2));
}
#else
struct V4 {
  float f[4];
};
inline V4 load4(const float* p) { return {{p[0], p[1], p[2], p[3]}}; }
inline V4 splat(float f) { return {{f, f, f, f}}; }
#define SL_V4_OP(name, expr)                                  \
  inline V4 name(V4 a, V4 b) {                                \
    V4 r;                                                     \
    for (int k = 0; k < 4; ++k) r.f[k] = expr(a.f[k], b.f[k]); \
    return r;                                                 \
  }
inline float fmin_(float a, float b) { return b < a ? b : a; }
inline float fmax_(float a, float b) { return a < b ? b : a; }
inline float add_(float a, float b) { return a + b; }
inline float sub_(float a, float b) { return a - b; }
inline float mul_(float a, float b) { return a * b; }
SL_V4_OP(vmin, fmin_)
SL_V4_OP(vmax, fmax_)
SL_V4_OP(operator+, add_)
SL_V4_OP(operator-, sub_)
SL_V4_OP(operator*, mul_)
#undef SL_V4_OP
inline float lane(V4 a, int k) { return a.f[k]; }
inline V4 drop_lane3(V4 a) { return a.f[3] = 0.0f, a; }
inline void bin_index(V4 c, V4 base, V4 scale, int bins, int out[4]) {
  for (int k = 0; k < 4; ++k) out[k] = std::max(0, std::min(bins - 1, static_cast<int>((c.f[k] - base.f[k]) * scale.f[k])));
}
inline float half_area(V4 lo, V4 hi) {
  float e[3];
  for (int k = 0; k < 3; ++k) e[k] = std::max(hi.f[k] - lo.f[k], 0.0f);
  return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
}
#endif

constexpr float kInf = std::numeric_limits<float>::infinity();

struct Box4 {
  V4 lo = splat(kInf), hi = splat(-kInf);
  void extend(const Box4& b) { lo = vmin(lo, b.lo), hi = vmax(hi, b.hi); }
  void extend(V4 p) { lo = vmin(lo, p), hi = vmax(hi, p); }
  float half_area() const { return render::half_area(lo, hi); }
};

// A triangle's box; lo[3] carries the mesh triangle index, hi[3] is 0.
struct alignas(32) PrimRef {
  float lo[3];
  uint32_t id;
  float hi[3];
  float zero;
};

inline Box4 box_of(const PrimRef& p) {
  Box4 b;
  b.lo = drop_lane3(load4(p.lo)), b.hi = load4(p.hi);  // drop the id lane
  return b;
}
inline V4 centroid2(const Box4& b) { return b.lo + b.hi; }  // twice the centroid

// A range of refs with its bounds and the bounds of its (doubled) centroids.
struct Range {
  uint32_t begin = 0, end = 0;
  Box4 box, centroids;
  int depth = 0;  // binary splits above it
  uint32_t size() const { return end - begin; }
};

// SAH with block granularity: testing one to kBlockWidth triangles costs the same.
inline float blocks(uint32_t n) { return static_cast<float>((n + Bvh::kBlockWidth - 1) / Bvh::kBlockWidth); }
constexpr float kTraversalCost = 1.0f;
constexpr float kBlockCost = 1.0f;

// Deeper than this, splits fall back to object medians, so the tree depth stays below kMaxDepth
// and the fixed traversal stack (kWidth − 1 entries per level) can never overflow.
constexpr int kMedianDepth = 96;
constexpr uint32_t kTaskThreshold = 2048;         // refs; smaller subtrees are built inline
constexpr size_t kParallelBuildThreshold = 16384;  // triangles; smaller meshes build on one thread

// Small ranges use fewer bins: one per triangle is as fine as the SAH can resolve them.
inline int bin_count(uint32_t n) { return static_cast<int>(std::min<uint32_t>(std::max<uint32_t>(n, 4), Bvh::kBins)); }

struct Bins {
  int bins;
  Box4 box[3][Bvh::kBins];  // only the first `bins` of each axis are used
  uint32_t count[3][Bvh::kBins];

  explicit Bins(int bins) : bins(bins) {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < bins; ++b) box[a][b] = Box4(), count[a][b] = 0;
  }
  void add(const PrimRef* refs, uint32_t begin, uint32_t end, V4 base, V4 scale) {
    for (uint32_t i = begin; i < end; ++i) {
      const Box4 b = box_of(refs[i]);
      int idx[4];
      bin_index(centroid2(b), base, scale, bins, idx);
      for (int a = 0; a < 3; ++a) box[a][idx[a]].extend(b), count[a][idx[a]]++;
    }
  }
};

struct BuildNode {  // default-initialised on purpose: the arena is not touched until used
  float lo[3][BvhNode::kWidth], hi[3][BvhNode::kWidth];
  uint32_t ref[BvhNode::kWidth];    // interior: build node index; leaf: first ref
  uint32_t count[BvhNode::kWidth];  // 0 for interior children
  int children;
};

struct Builder {
  PrimRef* refs;
  std::unique_ptr<BuildNode[]> arena;
  std::atomic<uint32_t> next_node{0};

  struct Split {
    int axis = -1, pos = 0;
    float cost = kInf;
  };

  // The cheapest bin plane of r by the SAH (cost without the traversal term, not divided by
  // r's area); axis −1 when no plane has triangles on both sides.
  Split find_split(const Range& r, V4& base, V4& scale) const {
    const uint32_t n = r.size();
    const int nb = bin_count(n);
    const V4 extent = r.centroids.hi - r.centroids.lo;
    base = r.centroids.lo;
    alignas(16) float s[4];
    for (int a = 0; a < 3; ++a) {
      const float e = lane(extent, a);
      s[a] = e > 0.0f ? static_cast<float>(nb) * 0.99999f / e : 0.0f;
    }
    s[3] = 0.0f;
    scale = load4(s);
    Bins bins(nb);
    bins.add(refs, r.begin, r.end, base, scale);
    Split best;
    for (int a = 0; a < 3; ++a) {
      if (s[a] == 0.0f) continue;
      float right_cost[Bvh::kBins];
      Box4 acc;
      uint32_t cnt = 0;
      for (int b = nb - 1; b > 0; --b) {
        acc.extend(bins.box[a][b]);
        cnt += bins.count[a][b];
        right_cost[b] = cnt ? acc.half_area() * blocks(cnt) : kInf;
      }
      acc = Box4();
      cnt = 0;
      for (int b = 0; b < nb - 1; ++b) {
        acc.extend(bins.box[a][b]);
        cnt += bins.count[a][b];
        if (cnt == 0 || cnt == n) continue;
        const float cost = acc.half_area() * blocks(cnt) + right_cost[b + 1];
        if (cost < best.cost) best.cost = cost, best.axis = a, best.pos = b + 1;
      }
    }
    return best;
  }

  // Partitions r by the split, computing both sides' bounds on the way.
  void partition(const Range& r, int axis, int pos, V4 base, V4 scale, Range& left, Range& right) const {
    uint32_t i = r.begin, j = r.end;
    const int nb = bin_count(r.size());
    auto goes_left = [&](const Box4& b) {
      int idx[4];
      bin_index(centroid2(b), base, scale, nb, idx);
      return idx[axis] < pos;
    };
    left = Range(), right = Range();
    for (;;) {
      while (i < j) {
        const Box4 b = box_of(refs[i]);
        if (!goes_left(b)) break;
        left.box.extend(b), left.centroids.extend(centroid2(b)), ++i;
      }
      while (i < j) {
        const Box4 b = box_of(refs[j - 1]);
        if (goes_left(b)) break;
        right.box.extend(b), right.centroids.extend(centroid2(b)), --j;
      }
      if (i >= j) break;
      std::swap(refs[i], refs[j - 1]);  // now both are on their side; the loops above extend
    }
    left.begin = r.begin, left.end = i, right.begin = i, right.end = r.end;
    left.depth = right.depth = r.depth + 1;
  }

  // Object median on the widest centroid axis (or halves by index when all centroids coincide).
  void median_split(const Range& r, Range& left, Range& right) const {
    const V4 e = r.centroids.hi - r.centroids.lo;
    const int axis = lane(e, 0) >= lane(e, 1) ? (lane(e, 0) >= lane(e, 2) ? 0 : 2) : (lane(e, 1) >= lane(e, 2) ? 1 : 2);
    const uint32_t mid = r.begin + r.size() / 2;
    if (lane(e, axis) > 0.0f)
      std::nth_element(refs + r.begin, refs + mid, refs + r.end, [axis](const PrimRef& a, const PrimRef& b) {
        return a.lo[axis] + a.hi[axis] < b.lo[axis] + b.hi[axis];
      });
    left = Range(), right = Range();
    for (uint32_t i = r.begin; i < r.end; ++i) {
      Range& side = i < mid ? left : right;
      const Box4 b = box_of(refs[i]);
      side.box.extend(b), side.centroids.extend(centroid2(b));
    }
    left.begin = r.begin, left.end = mid, right.begin = mid, right.end = r.end;
    left.depth = right.depth = r.depth + 1;
  }

  // How a range is split: not at all (a leaf), at its object median, or at a SAH bin plane.
  struct Plan {
    enum Kind { kLeaf, kMedian, kSah } kind = kLeaf;
    int axis = 0, pos = 0;
    V4 base, scale;
  };

  // `traversal_cost` is kTraversalCost when splitting r makes a new node, and 0 when r's halves
  // take free slots of the node being grown: testing one more child box there costs nothing.
  Plan plan(const Range& r, float traversal_cost) const {
    Plan p;
    const uint32_t n = r.size();
    if (n <= 1) return p;
    const bool small = n <= static_cast<uint32_t>(Bvh::kMaxLeafSize);
    const V4 e = r.centroids.hi - r.centroids.lo;
    const bool flat = !(lane(e, 0) > 0.0f || lane(e, 1) > 0.0f || lane(e, 2) > 0.0f);
    if (r.depth >= kMedianDepth || flat) {
      p.kind = small ? Plan::kLeaf : Plan::kMedian;
      return p;
    }
    const Split s = find_split(r, p.base, p.scale);
    const float area = r.box.half_area();
    if (small && (s.axis < 0 || !(traversal_cost * area + kBlockCost * s.cost < kBlockCost * blocks(n) * area)))
      return p;
    p.kind = s.axis < 0 ? Plan::kMedian : Plan::kSah;
    p.axis = s.axis, p.pos = s.pos;
    return p;
  }

  void apply(const Range& r, const Plan& p, Range& left, Range& right) const {
    if (p.kind == Plan::kSah) partition(r, p.axis, p.pos, p.base, p.scale, left, right);
    if (p.kind == Plan::kMedian || left.size() == 0 || right.size() == 0) median_split(r, left, right);
  }

  // Grows build node `index` over r: splits the child of largest area until kWidth children.
  // `first` is r's plan when the caller has made it already.
  void build(const Range& r, uint32_t index, const Plan* first) {
    Range kids[BvhNode::kWidth];
    Plan plans[BvhNode::kWidth];
    bool planned[BvhNode::kWidth] = {};
    int k = 1;
    kids[0] = r;
    if (first) plans[0] = *first, planned[0] = true;
    while (k < BvhNode::kWidth) {
      int pick = -1;
      float best = -1.0f;
      for (int i = 0; i < k; ++i) {
        if (planned[i] && plans[i].kind == Plan::kLeaf) continue;
        const float a = kids[i].box.half_area();
        if (a > best) best = a, pick = i;
      }
      if (pick < 0) break;
      if (!planned[pick]) plans[pick] = plan(kids[pick], 0.0f), planned[pick] = true;
      if (plans[pick].kind == Plan::kLeaf) continue;
      Range left, right;
      apply(kids[pick], plans[pick], left, right);
      kids[pick] = left, kids[k] = right;
      planned[pick] = planned[k] = false;
      ++k;
    }
    BuildNode& node = arena[index];
    node.children = k;
    for (int i = 0; i < k; ++i) {
      for (int a = 0; a < 3; ++a) node.lo[a][i] = lane(kids[i].box.lo, a), node.hi[a][i] = lane(kids[i].box.hi, a);
      // Children left unsplit because the node filled up are planned here: small ones may be leaves.
      if (!planned[i]) plans[i] = plan(kids[i], kTraversalCost), planned[i] = true;
      if (plans[i].kind == Plan::kLeaf) {
        node.ref[i] = kids[i].begin, node.count[i] = kids[i].size();
        continue;
      }
      const uint32_t child = next_node.fetch_add(1, std::memory_order_relaxed);
      node.ref[i] = child, node.count[i] = 0;
      if (kids[i].size() > kTaskThreshold) {
        const Range kid = kids[i];
        const Plan kid_plan = plans[i];
#pragma omp task default(shared) firstprivate(kid, child, kid_plan)
        build(kid, child, &kid_plan);
      } else {
        build(kids[i], child, &plans[i]);
      }
    }
#pragma omp taskwait
  }
};

// ---------------------------------------------------------------- pre-splits (bvh.h)

// A convex polygon: a triangle clipped by at most log2(kMaxSplitRefs) planes has at most 7 vertices.
struct Polygon {
  glm::vec3 v[16];
  int n = 0;
};

// Splits p by the plane x[axis] = pos into the parts below and above it.
void clip(const Polygon& p, int axis, float pos, Polygon& below, Polygon& above) {
  below.n = above.n = 0;
  for (int i = 0; i < p.n; ++i) {
    const glm::vec3 a = p.v[i], b = p.v[(i + 1) % p.n];
    const float da = a[axis] - pos, db = b[axis] - pos;
    if (da <= 0.0f) below.v[below.n++] = a;
    if (da >= 0.0f) above.v[above.n++] = a;
    if ((da < 0.0f && db > 0.0f) || (da > 0.0f && db < 0.0f)) {
      glm::vec3 q = a + (da / (da - db)) * (b - a);
      q[axis] = pos;
      below.v[below.n++] = q, above.v[above.n++] = q;
    }
  }
}

// The coarsest line of the power-of-two grid over [slo, slo + ext] strictly inside (lo, hi).
bool grid_plane(float lo, float hi, float slo, float ext, float& pos) {
  if (!(ext > 0.0f) || !(hi > lo)) return false;
  for (int level = 1; level <= 24; ++level) {
    const float cell = std::ldexp(ext, -level);
    const float m = std::floor((hi - slo) / cell);
    for (float k : {m, m - 1.0f}) {
      pos = slo + k * cell;
      if (pos > lo && pos < hi) return true;
    }
  }
  return false;
}

struct PreSplitter {
  Box4 scene;
  glm::vec3 tri_lo, tri_hi;  // the triangle's box: no reference box exceeds it
  float widen;               // outward rounding margin of clipped boxes
  uint32_t id;
  PrimRef* out;
  uint32_t count = 0;

  void emit(const Polygon& p) {
    glm::vec3 lo(kInf), hi(-kInf);
    for (int i = 0; i < p.n; ++i) lo = glm::min(lo, p.v[i]), hi = glm::max(hi, p.v[i]);
    // Clipped vertices carry a few roundings: widen, then clamp to the triangle's exact box.
    lo = glm::max(lo - widen, tri_lo), hi = glm::min(hi + widen, tri_hi);
    out[count++] = {{lo.x, lo.y, lo.z}, id, {hi.x, hi.y, hi.z}, 0.0f};
  }
  static glm::vec3 box_lo(const Polygon& p) {
    glm::vec3 lo(kInf);
    for (int i = 0; i < p.n; ++i) lo = glm::min(lo, p.v[i]);
    return lo;
  }
  static glm::vec3 box_hi(const Polygon& p) {
    glm::vec3 hi(-kInf);
    for (int i = 0; i < p.n; ++i) hi = glm::max(hi, p.v[i]);
    return hi;
  }
  static float area(glm::vec3 e) { return e.x * e.y + e.y * e.z + e.z * e.x; }

  // Splits p into `k` references (fewer when no grid line crosses a part's box).
  void split(const Polygon& p, uint32_t k) {
    if (k <= 1 || p.n < 3) return emit(p);
    const glm::vec3 lo = box_lo(p), hi = box_hi(p), e = hi - lo;
    const int axis = e.x >= e.y ? (e.x >= e.z ? 0 : 2) : (e.y >= e.z ? 1 : 2);
    float pos;
    if (!grid_plane(lo[axis], hi[axis], lane(scene.lo, axis), lane(scene.hi, axis) - lane(scene.lo, axis), pos))
      return emit(p);
    Polygon below, above;
    clip(p, axis, pos, below, above);
    if (below.n < 3 || above.n < 3) return emit(p);
    const float al = area(box_hi(below) - box_lo(below)), ar = area(box_hi(above) - box_lo(above));
    const float share = al + ar > 0.0f ? al / (al + ar) : 0.5f;
    const uint32_t kl = std::min(k - 1, std::max<uint32_t>(1, static_cast<uint32_t>(std::lround(share * static_cast<float>(k)))));
    split(below, kl);
    split(above, k - kl);
  }
};

// Replaces refs[0, n) by the pre-split references (bvh.h); returns their count.
uint32_t presplit(std::unique_ptr<PrimRef[]>& refs, uint32_t n, const std::vector<glm::vec3>& positions,
                  const std::vector<glm::uvec3>& triangles, const Box4& scene, float budget, bool parallel) {
  std::vector<float> priority(n);
  double total = 0.0;
#pragma omp parallel for schedule(static) if (parallel)
  for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
    const PrimRef& r = refs[static_cast<size_t>(i)];
    const glm::uvec3 t = triangles[r.id];
    const glm::vec3 p0 = positions[t.x], p1 = positions[t.y], p2 = positions[t.z];
    const float tri_area = 0.5f * glm::length(glm::cross(p1 - p0, p2 - p0));
    const glm::vec3 e(r.hi[0] - r.lo[0], r.hi[1] - r.lo[1], r.hi[2] - r.lo[2]);
    const float box_area = e.x * e.y + e.y * e.z + e.z * e.x;
    priority[static_cast<size_t>(i)] = std::sqrt(std::sqrt(std::max(box_area - tri_area, 0.0f)));
  }
  for (uint32_t i = 0; i < n; ++i) total += priority[i];  // in order: the same sum on any thread count
  if (!(total > 0.0)) return n;
  const double scale = static_cast<double>(budget) * n / total;
  std::vector<uint64_t> offset(static_cast<size_t>(n) + 1, 0);
  for (uint32_t i = 0; i < n; ++i) {
    const double k = std::floor(1.0 + priority[i] * scale);
    offset[i + 1] = offset[i] + static_cast<uint64_t>(std::min<double>(k, Bvh::kMaxSplitRefs));
  }
  if (offset[n] == n) return n;
  SL_CHECK(offset[n] < (uint64_t{1} << 31), "Bvh: ", offset[n], " references exceed 2^31");
  std::unique_ptr<PrimRef[]> out(new PrimRef[offset[n]]);
  std::vector<uint32_t> made(n);
#pragma omp parallel for schedule(dynamic, 1024) if (parallel)
  for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
    const size_t j = static_cast<size_t>(i);
    const PrimRef& r = refs[j];
    const uint32_t k = static_cast<uint32_t>(offset[j + 1] - offset[j]);
    if (k == 1) {
      out[offset[j]] = r, made[j] = 1;
      continue;
    }
    const glm::uvec3 t = triangles[r.id];
    Polygon p;
    p.n = 3, p.v[0] = positions[t.x], p.v[1] = positions[t.y], p.v[2] = positions[t.z];
    PreSplitter s;
    s.scene = scene, s.tri_lo = glm::vec3(r.lo[0], r.lo[1], r.lo[2]), s.tri_hi = glm::vec3(r.hi[0], r.hi[1], r.hi[2]);
    const glm::vec3 mag = glm::max(glm::abs(s.tri_lo), glm::abs(s.tri_hi));
    s.widen = 4e-6f * std::max({mag.x, mag.y, mag.z, 1e-30f});
    s.id = r.id, s.out = &out[offset[j]];
    s.split(p, k);
    made[j] = s.count;
  }
  // Compact in order: the references (and so the tree) do not depend on the thread count.
  uint32_t m = 0;
  for (uint32_t i = 0; i < n; ++i) {
    if (m != offset[i]) std::memmove(&out[m], &out[offset[i]], made[i] * sizeof(PrimRef));
    m += made[i];
  }
  refs = std::move(out);
  return m;
}

// Lays out build node `b` and its subtree depth-first; returns its index in nodes_.
struct BvhLayout {
  const Builder& builder;
  const std::vector<glm::vec3>& positions;
  const std::vector<glm::uvec3>& triangles;
  std::vector<BvhNode, BvhAllocator<BvhNode>>& nodes;
  std::vector<Bvh::TriangleBlock, BvhAllocator<Bvh::TriangleBlock>>& blocks;
  int depth = 0;
  size_t slots = 0;  // leaf slots written

  // Lanes used in the last block; kBlockWidth when there is no block with free lanes.
  uint32_t last_used = Bvh::kBlockWidth;

  // Leaves share blocks: a leaf of at most the last block's free lanes goes there, any other
  // starts a new block (so a leaf crosses blocks only when it has more than kBlockWidth
  // triangles). Random rays miss in cache on most leaves they test: with each leaf in blocks of
  // its own, the 200k-triangle test mesh filled 67% of its lanes.
  uint32_t leaf(uint32_t first, uint32_t count) {
    // Pre-split references of one triangle that meet in a leaf take one slot.
    uint32_t ids[Bvh::kMaxLeafSize];
    uint32_t unique = 0;
    for (uint32_t i = 0; i < count; ++i) {
      const uint32_t id = builder.refs[first + i].id;
      if (std::find(ids, ids + unique, id) == ids + unique) ids[unique++] = id;
    }
    count = unique;
    slots += count;
    const bool share = count <= Bvh::kBlockWidth - last_used;
    const uint32_t block = static_cast<uint32_t>(blocks.size()) - (share ? 1 : 0), lane = share ? last_used : 0;
    SL_CHECK(block < (1u << 24), "Bvh: more than 2^24 triangle blocks");
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (uint32_t i = 0; i < count; ++i) {
      const uint32_t slot = block * Bvh::kBlockWidth + lane + i, b = slot / Bvh::kBlockWidth, l = slot % Bvh::kBlockWidth;
      if (b == blocks.size()) {  // a new block: unused lanes stay NaN and never hit
        Bvh::TriangleBlock tb;
        std::fill(&tb.v[0][0][0], &tb.v[0][0][0] + 9 * Bvh::kBlockWidth, nan);
        std::fill(tb.id, tb.id + Bvh::kBlockWidth, Hit::kNone);
        blocks.push_back(tb);
      }
      const uint32_t id = ids[i];
      blocks[b].id[l] = id;
      for (int v = 0; v < 3; ++v) {
        const glm::vec3 p = positions[triangles[id][v]];
        for (int a = 0; a < 3; ++a) blocks[b].v[v][a][l] = p[a];
      }
    }
    last_used = (lane + count - 1) % Bvh::kBlockWidth + 1;
    return BvhNode::kLeafBit | (block << 7) | (lane << 4) | (count - 1);
  }

  uint32_t node(uint32_t b, int level) {
    depth = std::max(depth, level + 1);
    const BuildNode& in = builder.arena[b];
    const uint32_t index = static_cast<uint32_t>(nodes.size());
    nodes.emplace_back();
    {
      BvhNode& out = nodes.back();
      for (int i = 0; i < BvhNode::kWidth; ++i) {
        const bool used = i < in.children;
        for (int a = 0; a < 3; ++a) {
          out.bounds[a][i] = used ? in.lo[a][i] : std::numeric_limits<float>::infinity();
          out.bounds[3 + a][i] = used ? in.hi[a][i] : -std::numeric_limits<float>::infinity();
        }
        out.child[i] = BvhNode::kEmpty;
        out.reserved[i] = 0;
      }
    }
    // The node's leaves first, so that siblings share blocks, then its subtrees depth-first.
    for (int i = 0; i < in.children; ++i)
      if (in.count[i]) nodes[index].child[i] = leaf(in.ref[i], in.count[i]);
    for (int i = 0; i < in.children; ++i)
      if (!in.count[i]) nodes[index].child[i] = node(in.ref[i], level + 1);  // assigned after: nodes may grow
    return index;
  }
};

}  // namespace

Bvh::Bvh(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
         const BvhBuildOptions& options) {
  const size_t count = triangles.size();
  SL_CHECK(count < (size_t{1} << 31), "Bvh: ", count, " triangles exceed 2^31");
  std::unique_ptr<PrimRef[]> refs(new PrimRef[count]);
  const bool parallel = !omp_in_parallel() && count >= kParallelBuildThreshold && omp_get_max_threads() > 1;
  const int chunks = parallel ? omp_get_max_threads() : 1;
  std::vector<size_t> kept(static_cast<size_t>(chunks) + 1, 0);
  std::vector<int64_t> bad(static_cast<size_t>(chunks), -1);
  std::vector<Box4> root_box(static_cast<size_t>(chunks)), root_centroids(static_cast<size_t>(chunks));
  const size_t npos = positions.size();
  // Two passes per chunk: keep each chunk's valid refs at its start, then compact in order, so
  // the ref order (and the tree) does not depend on the thread count.
#pragma omp parallel for num_threads(chunks) schedule(static, 1) if (chunks > 1)
  for (int c = 0; c < chunks; ++c) {
    const size_t begin = count * static_cast<size_t>(c) / static_cast<size_t>(chunks);
    const size_t end = count * static_cast<size_t>(c + 1) / static_cast<size_t>(chunks);
    size_t out = begin;
    Box4 box, centroids;
    for (size_t t = begin; t < end; ++t) {
      const glm::uvec3 tri = triangles[t];
      if (tri.x >= npos || tri.y >= npos || tri.z >= npos) {
        if (bad[static_cast<size_t>(c)] < 0) bad[static_cast<size_t>(c)] = static_cast<int64_t>(t);
        continue;
      }
      const glm::vec3 p0 = positions[tri.x], p1 = positions[tri.y], p2 = positions[tri.z];
      // Zero-area and non-finite triangles can never be hit (det = 0 or NaN): leave them out.
      if (!std::isfinite(p0.x + p0.y + p0.z + p1.x + p1.y + p1.z + p2.x + p2.y + p2.z)) continue;
      const glm::vec3 n = glm::cross(p1 - p0, p2 - p0);
      if (n.x == 0.0f && n.y == 0.0f && n.z == 0.0f) continue;
      const glm::vec3 lo = glm::min(p0, glm::min(p1, p2)), hi = glm::max(p0, glm::max(p1, p2));
      PrimRef& r = refs[out++];
      r = {{lo.x, lo.y, lo.z}, static_cast<uint32_t>(t), {hi.x, hi.y, hi.z}, 0.0f};
      const Box4 b = box_of(r);
      box.extend(b), centroids.extend(centroid2(b));
    }
    kept[static_cast<size_t>(c) + 1] = out - begin;
    root_box[static_cast<size_t>(c)] = box, root_centroids[static_cast<size_t>(c)] = centroids;
  }
  for (int c = 0; c < chunks; ++c) {
    const int64_t t = bad[static_cast<size_t>(c)];
    SL_CHECK(t < 0, "Bvh: triangle ", t, " has a vertex index out of range [0, ", npos, ")");
  }
  Range root;
  for (int c = 0; c < chunks; ++c) {
    const size_t begin = count * static_cast<size_t>(c) / static_cast<size_t>(chunks);
    const size_t n = kept[static_cast<size_t>(c) + 1];
    if (n && begin != kept[static_cast<size_t>(c)]) std::memmove(&refs[kept[static_cast<size_t>(c)]], &refs[begin], n * sizeof(PrimRef));
    kept[static_cast<size_t>(c) + 1] += kept[static_cast<size_t>(c)];
    root.box.extend(root_box[static_cast<size_t>(c)]), root.centroids.extend(root_centroids[static_cast<size_t>(c)]);
  }
  uint32_t n = static_cast<uint32_t>(kept[static_cast<size_t>(chunks)]);
  triangle_count_ = n;
  if (n == 0) return;
  if (options.split_budget > 0.0f && n > 1) {
    n = presplit(refs, n, positions, triangles, root.box, options.split_budget, parallel);
    root.box = Box4(), root.centroids = Box4();
    for (uint32_t i = 0; i < n; ++i) {
      const Box4 b = box_of(refs[i]);
      root.box.extend(b), root.centroids.extend(centroid2(b));
    }
  }
  root.begin = 0, root.end = n;
  for (int a = 0; a < 3; ++a) bounds_.lo[a] = lane(root.box.lo, a), bounds_.hi[a] = lane(root.box.hi, a);

  // Every interior node has at least two children, so there are fewer nodes than refs.
  Builder builder;
  builder.refs = refs.get();
  builder.arena.reset(new BuildNode[std::max<uint32_t>(n, 1)]);
  builder.next_node = 1;
#pragma omp parallel if (parallel)
#pragma omp single
  builder.build(root, 0, nullptr);

  const uint32_t node_count = builder.next_node.load();
  size_t block_count = 0;
  for (uint32_t b = 0; b < node_count; ++b)
    for (int i = 0; i < builder.arena[b].children; ++i) block_count += (builder.arena[b].count[i] + kBlockWidth - 1) / kBlockWidth;
  nodes_.reserve(node_count);
  blocks_.reserve(block_count);
  BvhLayout layout{builder, positions, triangles, nodes_, blocks_};
  layout.node(0, 0);
  reference_count_ = layout.slots;
  depth_ = layout.depth + 1;  // the leaf level
  prefetch_ = nodes_.size() * sizeof(BvhNode) + blocks_.size() * sizeof(TriangleBlock) > l2_cache_bytes();
  SL_CHECK(depth_ <= kMaxDepth, "Bvh: tree depth ", depth_, " exceeds ", kMaxDepth);
}

}  // namespace sl::render
