// Bvh queries: 8-wide box tests, blocks of watertight ray-triangle tests, ordered traversal.
// Compiled with -ffp-contract=off (render/CMakeLists.txt): the triangle test must round each
// edge function the same way for both triangles of a shared edge, in every lane.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "render/bvh.h"
#include "render/bvh_ray_tests.inc"
#include "util/error.h"

namespace sl::render {
namespace {

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
