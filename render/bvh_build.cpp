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

// ---------------------------------------------------------------- pre-splits
#include "render/bvh_presplit.inc"  // part of this file, in this unnamed namespace

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
