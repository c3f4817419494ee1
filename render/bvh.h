// Bounding volume hierarchy over a triangle mesh: closest-hit and occlusion queries.
//
// Build: binned SAH (Wald 2007) over all three axes with kBins bins, subtrees built as OpenMP
// tasks, flattened depth-first into 32-byte nodes (pbrt's LinearBVHNode layout: the first child
// follows its parent, the second is at `offset`). Leaves hold at most kMaxLeafSize triangles,
// stored as vertex copies in leaf order so a leaf is one contiguous read.
// Intersection: watertight ray-triangle test (Woop, Benthin & Wald, JCGT 2013): a ray through
// an edge or vertex shared by two triangles hits at least one of them, never slips between.
// Node boxes are tested with a precomputed inverse direction and far distances widened by
// 1 + 2γ₃ (pbrt §6.8.2), so a triangle hit is never culled by box rounding.
// Guarantees:
//   - a hit has tmin < t < tmax; the hit point is (1-u-v)·p0 + u·p1 + v·p2 of the mesh triangle
//     `triangle` (its index in Mesh::triangles);
//   - zero-area triangles, and triangles with non-finite vertices, are left out and never hit;
//   - a ray lying in a triangle's plane misses it (its determinant is zero);
//   - a ray starting on a surface with tmin = ε > 0 does not hit that surface at t ≈ 0;
//   - a ray with a zero or non-finite direction, or a NaN origin, misses;
//   - an empty mesh gives an empty BVH in which every ray misses;
//   - results do not depend on the thread count (queries are independent per ray).
// Throws: sl::Error when a triangle's vertex index is out of range.
#pragma once
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "render/mesh.h"

namespace sl {

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

struct alignas(32) BvhNode {
  float lo[3];
  uint32_t offset;  // leaf: first triangle slot; interior: index of the second child
  float hi[3];
  uint16_t count;   // triangles in a leaf; 0 for an interior node
  uint16_t axis;    // split axis of an interior node
};
static_assert(sizeof(BvhNode) == 32, "BvhNode must stay one half cache line");
static_assert(offsetof(BvhNode, hi) == 16, "traversal reads hi[k] as float 4 + k of the node");

class Bvh {
 public:
  static constexpr int kBins = 32;
  static constexpr int kMaxLeafSize = 4;

  Bvh() = default;  // empty: every ray misses
  explicit Bvh(const Mesh& mesh) : Bvh(mesh.positions, mesh.triangles) {}
  Bvh(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles);

  Hit intersect(const Ray& ray) const;
  bool occluded(const Ray& ray) const;  // any hit in (tmin, tmax)

  // Batch queries over OpenMP; hits/occluded must hold `count` entries.
  void intersect(const Ray* rays, Hit* hits, size_t count) const;
  void occluded(const Ray* rays, uint8_t* occluded, size_t count) const;

  bool empty() const { return nodes_.empty(); }
  size_t node_count() const { return nodes_.size(); }
  size_t triangle_count() const { return ids_.size(); }  // triangles kept (non-degenerate)
  Bounds3 bounds() const;
  const std::vector<BvhNode>& nodes() const { return nodes_; }
  int depth() const { return depth_; }

  struct Triangle {
    float p0[3], p1[3], p2[3];
  };

 private:
  template <bool kAnyHit>
  Hit traverse(const Ray& ray) const;

  std::vector<BvhNode> nodes_;
  std::vector<Triangle> triangles_;  // leaf order
  std::vector<uint32_t> ids_;        // leaf slot -> mesh triangle index
  int depth_ = 0;
};

// Reference: tests every triangle with the same watertight test (for tests and validation).
Hit intersect_brute_force(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
                          const Ray& ray);

}  // namespace sl
