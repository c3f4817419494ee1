// Bounding volume hierarchy over a triangle mesh: closest-hit and occlusion queries.
//
// Build (bvh_build.cpp): binned SAH (Wald 2007) over all three axes with kBins bins, grown
// directly into an 8-wide tree: a node repeatedly splits its child of largest surface area until
// it has kWidth children (the collapse of Wald, Benthin & Boulos 2008, done while building). A
// split that fills a free slot is judged by the SAH without a traversal cost, since one more box
// in a node already being tested costs nothing, so nodes are fuller and leaves smaller.
// Subtrees are built as OpenMP tasks; the tree does not depend on the schedule. The result is laid
// out depth-first: nodes store their children's boxes as structure-of-arrays, so one node is
// tested against a ray with a few 8-wide vector instructions. Leaves hold at most kMaxLeafSize
// triangles, stored as vertex copies in blocks of kBlockWidth (structure-of-arrays), so a leaf
// is one contiguous read and its triangles are tested together; a node's small leaves share
// blocks (a leaf starts at any lane), so the lanes hold triangles rather than padding.
// Pre-splits (BvhBuildOptions::split_budget; Karras & Aila 2013, Embree's presplits): before the
// SAH build, triangles whose boxes are large for their area (long, thin, diagonal slivers, large
// walls) get several references, each bounding the part of the triangle inside one cell of a
// power-of-two grid over the mesh's box. A leaf tests whole triangles, so a reference's box only
// has to contain its part of the triangle; boxes are rounded outwards, so every hit point lies
// in some reference's box. A triangle may then appear in several leaves (never twice in one).
// Intersection (bvh.cpp; its ray tests in bvh_ray_tests.inc): watertight ray-triangle test
// (Woop, Benthin & Wald, JCGT 2013): a ray through an edge or vertex shared by two triangles
// hits at least one of them, never slips between. Every lane of the vector test performs the same IEEE operations, in the same order,
// as the scalar test of intersect_brute_force. Child boxes are tested with a precomputed inverse
// direction and far distances widened by 1 + 2γ₄ (pbrt §6.8.2), so a triangle hit is never
// culled by box rounding. Closest-hit visits children nearest first and skips deferred subtrees
// that start beyond the nearest hit so far; occlusion stops at the first hit it finds. Children at
// equal entry distances go in a fixed order (two: the lower slot first; more: the higher), which
// decides which of two triangles at exactly the same t is reported; under AVX-512 three or more
// children are sorted by a branch-free network on (distance, slot) keys in that same order. Under
// AVX-512 the prefetching traversal (trees larger than the L2 cache) tests a leaf of 9-16
// triangles, which spans two blocks, in one 16-wide pass with the same operations per lane.
// Guarantees:
//   - a hit has tmin < t < tmax; the hit point is (1-u-v)·p0 + u·p1 + v·p2 of the mesh triangle
//     `triangle` (its index in Mesh::triangles);
//   - zero-area triangles, and triangles with non-finite vertices, are left out and never hit;
//   - a ray lying in a triangle's plane misses it (its determinant is zero);
//   - a ray starting on a surface with tmin = ε > 0 does not hit that surface at t ≈ 0;
//   - a tmin below 0 is read as 0: nothing behind the origin is hit (intersect_brute_force alike);
//   - a ray with a zero or non-finite direction, or a NaN origin, misses;
//   - an empty mesh gives an empty BVH in which every ray misses;
//   - results do not depend on the thread count (queries are independent per ray, and the
//     tree does not depend on how the build was scheduled);
//   - the 8-wide AVX2 tests, AVX-512 child ordering and AVX-512's 16-wide test of a leaf over two
//     blocks (when compiled for them) and the portable lane loops, forced with
//     use_portable_kernels(true), give bit-identical hits, ties included.
// Throws: sl::Error when a triangle's vertex index is out of range.
#pragma once
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "render/mesh.h"

namespace sl::render {

struct Ray {
  glm::vec3 origin{0.0f};
  float tmin = 0.0f;
  glm::vec3 direction{0.0f, 0.0f, 1.0f};  // need not be unit; t is in units of |direction|
  float tmax = std::numeric_limits<float>::infinity();
};

struct Hit {
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  float t = std::numeric_limits<float>::infinity();
  uint32_t triangle = kNone;
  float u = 0.0f, v = 0.0f;  // barycentric weights of the triangle's 2nd and 3rd vertex
  bool hit() const { return triangle != kNone; }
};

// One 8-wide interior node: the boxes of its children as structure-of-arrays, then their
// references. An unused slot has an empty box (lo = +∞, hi = −∞), which no ray enters.
struct alignas(64) BvhNode {
  static constexpr int kWidth = 8;
  static constexpr uint32_t kLeafBit = 0x80000000u;  // child ref: leaf (else an index into nodes())
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;    // child ref of an unused slot
  // bounds[a][i]: a = 0..2 lo x, y, z; a = 3..5 hi x, y, z; i = child slot.
  float bounds[6][kWidth];
  uint32_t child[kWidth];
  uint32_t reserved[kWidth];  // pads the node to four cache lines

  // A leaf ref packs its first triangle block, its first lane in that block and its triangle
  // count (1..kMaxLeafSize): leaf triangles are the consecutive slots block·8 + lane onwards.
  static bool is_leaf(uint32_t ref) { return (ref & kLeafBit) != 0; }
  static uint32_t leaf_block(uint32_t ref) { return (ref & ~kLeafBit) >> 7; }
  static uint32_t leaf_lane(uint32_t ref) { return (ref >> 4) & 7u; }
  static uint32_t leaf_count(uint32_t ref) { return (ref & 15u) + 1; }
};
static_assert(sizeof(BvhNode) == 256, "BvhNode must stay four cache lines");

// Allocator for the BVH's arrays: blocks of 2 MiB and more are 2 MiB-aligned and, on Linux,
// marked for transparent huge pages, so random traversal does not miss in the TLB at every step.
void* bvh_allocate(size_t bytes);
void bvh_deallocate(void* p, size_t bytes);
template <class T>
struct BvhAllocator {
  using value_type = T;
  BvhAllocator() = default;
  template <class U>
  BvhAllocator(const BvhAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(bvh_allocate(n * sizeof(T))); }
  void deallocate(T* p, size_t n) { bvh_deallocate(p, n * sizeof(T)); }
  template <class U>
  bool operator==(const BvhAllocator<U>&) const { return true; }
};

struct BvhBuildOptions {
  // Extra references from pre-splits, as a share of the triangles (0: none). Each triangle gets
  // 1 + floor(budget · n · p / Σp) references (at most kMaxSplitRefs), p being the fourth root of
  // its box's half area less its own area, so only triangles well above the mean are split.
  float split_budget = 0.0f;
};

class Bvh {
 public:
  static constexpr int kBins = 32;
  static constexpr int kBlockWidth = 8;   // triangles tested together
  static constexpr int kMaxLeafSize = 16; // at most 16 (leaf refs keep the count in 4 bits)
  static constexpr int kMaxDepth = 128;   // levels; the build falls back to median splits long before
  static constexpr int kMaxSplitRefs = 16;  // references per triangle from pre-splits

  // kBlockWidth triangles as structure-of-arrays: v[vertex][axis][lane]. Unused lanes are NaN.
  // id: each lane's mesh triangle (Hit::kNone when unused). Kept in the block, so the hit's id is
  // read from a line the triangle test has just loaded: in a separate array it was one more cache
  // miss per hit ray on meshes larger than the L2 cache. 320 bytes, five whole cache lines.
  struct alignas(64) TriangleBlock {
    float v[3][3][kBlockWidth];
    uint32_t id[kBlockWidth];
  };

  Bvh() = default;  // empty: every ray misses
  explicit Bvh(const Mesh& mesh, const BvhBuildOptions& options = default_options())
      : Bvh(mesh.positions, mesh.triangles, options) {}
  Bvh(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
      const BvhBuildOptions& options = default_options());
  static BvhBuildOptions default_options() { return {}; }

  Hit intersect(const Ray& ray) const;
  bool occluded(const Ray& ray) const;  // any hit in (tmin, tmax)

  // Batch queries over OpenMP; hits/occluded must hold `count` entries.
  void intersect(const Ray* rays, Hit* hits, size_t count) const;
  void occluded(const Ray* rays, uint8_t* occluded, size_t count) const;

  // Queries use the AVX2 box and triangle tests when the library was compiled for AVX2, else
  // portable lane loops; `true` forces the portable ones (for tests and comparisons).
  void use_portable_kernels(bool on) { portable_kernels_ = on; }
  bool uses_portable_kernels() const { return portable_kernels_; }

  // Whether traversal prefetches the children a ray enters: chosen by the build (prefetch_
  // below); settable so tests can run both traversals. Results do not depend on it.
  void use_prefetch(bool on) { prefetch_ = on; }
  bool uses_prefetch() const { return prefetch_; }

  bool empty() const { return nodes_.empty(); }
  size_t node_count() const { return nodes_.size(); }
  size_t triangle_count() const { return triangle_count_; }  // triangles kept (non-degenerate)
  size_t reference_count() const { return reference_count_; }  // leaf slots: triangles + pre-split copies
  Bounds3 bounds() const { return bounds_; }
  // Node 0 is the root; a non-empty BVH always has one, even over a single triangle.
  const std::vector<BvhNode, BvhAllocator<BvhNode>>& nodes() const { return nodes_; }
  int depth() const { return depth_; }  // nodes on the longest root-to-leaf path, the leaf included

 private:
  // SimdRay: which set of box and triangle tests; kPrefetch: whether entered children are
  // prefetched (prefetch_ below).
  template <bool kAnyHit, class SimdRay, bool kPrefetch>
  Hit traverse(const Ray& ray) const;
  template <bool kAnyHit>
  Hit dispatch(const Ray& ray) const;

  std::vector<BvhNode, BvhAllocator<BvhNode>> nodes_;
  std::vector<TriangleBlock, BvhAllocator<TriangleBlock>> blocks_;  // leaf order
  size_t triangle_count_ = 0;
  size_t reference_count_ = 0;
  Bounds3 bounds_;
  int depth_ = 0;
  bool portable_kernels_ = false;
  // Prefetch the children a ray enters only when the tree (nodes and triangle blocks) is larger
  // than the CPU's L2 cache: a tree that fits is served from L2 after the first rays, and the
  // prefetches (five per entered child) are then only extra load instructions.
  bool prefetch_ = true;
};

// Reference: tests every triangle with the same watertight test (for tests and validation).
Hit intersect_brute_force(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
                          const Ray& ray);

}  // namespace sl::render
