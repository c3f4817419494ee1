#include "render/bvh.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "autodiff/error.h"

namespace sl {
namespace {

// ---------------------------------------------------------------- ray-triangle (Woop et al. 2013)

struct PreparedRay {
  float o[3];          // origin
  float inv[3];        // 1 / direction (±∞ for a zero component)
  int near_at[3];      // float index of the entry slab in a BvhNode: lo[k] (k) or hi[k] (4 + k)
  float ox, oy, oz;    // origin permuted to (kx, ky, kz)
  float sx, sy, sz;    // shear constants, Sec. 3 of the paper
  int kx, ky, kz;
  float tmin;
  bool valid;
};

PreparedRay prepare(const Ray& ray) {
  PreparedRay r{};
  const float d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  r.o[0] = ray.origin.x, r.o[1] = ray.origin.y, r.o[2] = ray.origin.z;
  const float ad[3] = {std::fabs(d[0]), std::fabs(d[1]), std::fabs(d[2])};
  r.valid = std::isfinite(d[0]) && std::isfinite(d[1]) && std::isfinite(d[2]) &&
            std::isfinite(r.o[0] + r.o[1] + r.o[2]) && (ad[0] > 0 || ad[1] > 0 || ad[2] > 0) &&
            !std::isnan(ray.tmin) && !std::isnan(ray.tmax);
  if (!r.valid) return r;
  // kz: the dominant axis; swapping kx and ky when d[kz] < 0 keeps the winding (paper, Fig. 2).
  r.kz = ad[0] > ad[1] ? (ad[0] > ad[2] ? 0 : 2) : (ad[1] > ad[2] ? 1 : 2);
  r.kx = (r.kz + 1) % 3;
  r.ky = (r.kx + 1) % 3;
  if (d[r.kz] < 0.0f) std::swap(r.kx, r.ky);
  r.sx = d[r.kx] / d[r.kz];
  r.sy = d[r.ky] / d[r.kz];
  r.sz = 1.0f / d[r.kz];
  r.ox = r.o[r.kx], r.oy = r.o[r.ky], r.oz = r.o[r.kz];
  for (int k = 0; k < 3; ++k) {
    r.inv[k] = 1.0f / d[k];
    r.near_at[k] = std::signbit(r.inv[k]) ? 4 + k : k;
  }
  r.tmin = ray.tmin;
  return r;
}

// Returns true and sets t, u, v when the ray hits the triangle with tmin < t < tmax.
inline bool hit_triangle(const PreparedRay& r, const Bvh::Triangle& tri, float tmax, float& t, float& u, float& v) {
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

// 1 + 2γ₃ with γₙ = nε/(1 - nε), ε = 2⁻²⁴ (pbrt-v3 §3.9.2, used in Bounds3::IntersectP).
constexpr float kFarScale = 1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f);

// Slab test. Returns the entry distance in tnear when [tnear, tfar] meets [tmin, tmax].
// A zero direction component gives 0·∞ = NaN when the origin lies on that slab's plane; the
// comparisons below are written so a NaN entry acts as −∞ and a NaN exit as +∞ (the ray runs
// inside the plane, so that slab does not limit it).
inline bool hit_box(const BvhNode& n, const PreparedRay& r, float tmax, float& tnear) {
  // The node read as 8 floats: lo[0..2] at 0..2, hi[0..2] at 4..6 (static_assert on the layout).
  const float* f = reinterpret_cast<const float*>(&n);
  const float nx = (f[r.near_at[0]] - r.o[0]) * r.inv[0], fx = (f[r.near_at[0] ^ 4] - r.o[0]) * r.inv[0];
  const float ny = (f[r.near_at[1]] - r.o[1]) * r.inv[1], fy = (f[r.near_at[1] ^ 4] - r.o[1]) * r.inv[1];
  const float nz = (f[r.near_at[2]] - r.o[2]) * r.inv[2], fz = (f[r.near_at[2] ^ 4] - r.o[2]) * r.inv[2];
  float near = r.tmin;
  near = near < nx ? nx : near;
  near = near < ny ? ny : near;
  near = near < nz ? nz : near;
  float far = std::numeric_limits<float>::infinity();
  far = fx < far ? fx : far;
  far = fy < far ? fy : far;
  far = fz < far ? fz : far;
  tnear = near;
  return near <= far * kFarScale && near <= tmax;
}

// ---------------------------------------------------------------- build

struct PrimRef {
  Bounds3 box;
  glm::vec3 centroid;
  uint32_t slot;  // index into the kept-triangle arrays
};

struct BuildNode {
  Bounds3 box;
  uint32_t first = 0, count = 0;
  int axis = 0;
  std::unique_ptr<BuildNode> child[2];
};

// Deeper than this, splits fall back to object medians, so depth stays below kMaxDepth and the
// fixed traversal stack can never overflow.
constexpr int kMedianDepth = 96;
constexpr int kMaxDepth = 128;
constexpr int kTaskThreshold = 4096;

struct Builder {
  std::vector<PrimRef>& refs;

  std::unique_ptr<BuildNode> build(uint32_t begin, uint32_t end, int depth) {
    auto node = std::make_unique<BuildNode>();
    Bounds3 centroids;
    for (uint32_t i = begin; i < end; ++i) {
      node->box.extend(refs[i].box);
      centroids.extend(refs[i].centroid);
    }
    const uint32_t n = end - begin;
    node->first = begin;
    node->count = n;
    if (n <= 1) return node;

    uint32_t mid = split(begin, end, node->box, centroids, depth, node->axis);
    if (mid == begin || mid == end) return node;  // leaf (SAH prefers it, or it is small and flat)
    node->count = 0;
    if (n > kTaskThreshold) {
#pragma omp task default(shared) firstprivate(begin, mid, depth)
      node->child[0] = build(begin, mid, depth + 1);
      node->child[1] = build(mid, end, depth + 1);
#pragma omp taskwait
    } else {
      node->child[0] = build(begin, mid, depth + 1);
      node->child[1] = build(mid, end, depth + 1);
    }
    return node;
  }

  // Returns the partition point, or begin to request a leaf.
  uint32_t split(uint32_t begin, uint32_t end, const Bounds3& box, const Bounds3& centroids, int depth, int& axis_out) {
    const uint32_t n = end - begin;
    const glm::vec3 extent = centroids.extent();
    const int widest = extent.x >= extent.y ? (extent.x >= extent.z ? 0 : 2) : (extent.y >= extent.z ? 1 : 2);
    axis_out = widest;
    auto median = [&](int axis) {
      const uint32_t mid = begin + n / 2;
      std::nth_element(refs.begin() + begin, refs.begin() + mid, refs.begin() + end,
                       [axis](const PrimRef& a, const PrimRef& b) { return a.centroid[axis] < b.centroid[axis]; });
      return mid;
    };
    if (!(extent[widest] > 0.0f)) return n <= Bvh::kMaxLeafSize ? begin : begin + n / 2;  // all centroids equal
    if (depth >= kMedianDepth) return median(widest);

    // Binned SAH on every axis: cost = C_trav + (A_L·N_L + A_R·N_R) / A, with C_trav = 1 and
    // one unit per triangle test; a leaf costs N.
    struct Bin {
      Bounds3 box;
      uint32_t count = 0;
    };
    float best_cost = std::numeric_limits<float>::infinity();
    int best_axis = -1, best_split = 0;
    for (int axis = 0; axis < 3; ++axis) {
      if (!(extent[axis] > 0.0f)) continue;
      Bin bins[Bvh::kBins];
      const float lo = centroids.lo[axis], scale = Bvh::kBins / extent[axis];
      for (uint32_t i = begin; i < end; ++i) {
        const int b = std::min(Bvh::kBins - 1, static_cast<int>((refs[i].centroid[axis] - lo) * scale));
        bins[b].count++;
        bins[b].box.extend(refs[i].box);
      }
      float right_area[Bvh::kBins];
      uint32_t right_count[Bvh::kBins];
      Bounds3 acc;
      uint32_t cnt = 0;
      for (int b = Bvh::kBins - 1; b > 0; --b) {
        acc.extend(bins[b].box);
        cnt += bins[b].count;
        right_area[b] = acc.half_area();
        right_count[b] = cnt;
      }
      acc = Bounds3();
      cnt = 0;
      for (int b = 0; b < Bvh::kBins - 1; ++b) {
        acc.extend(bins[b].box);
        cnt += bins[b].count;
        if (cnt == 0 || right_count[b + 1] == 0) continue;
        const float cost = acc.half_area() * cnt + right_area[b + 1] * right_count[b + 1];
        if (cost < best_cost) best_cost = cost, best_axis = axis, best_split = b + 1;
      }
    }
    const float area = box.half_area();
    const float split_cost = area > 0.0f ? 1.0f + best_cost / area : static_cast<float>(n);
    if (best_axis < 0) return n <= Bvh::kMaxLeafSize ? begin : median(widest);
    if (n <= Bvh::kMaxLeafSize && static_cast<float>(n) <= split_cost) return begin;
    axis_out = best_axis;
    const float lo = centroids.lo[best_axis], scale = Bvh::kBins / extent[best_axis];
    auto it = std::partition(refs.begin() + begin, refs.begin() + end, [&](const PrimRef& p) {
      return std::min(Bvh::kBins - 1, static_cast<int>((p.centroid[best_axis] - lo) * scale)) < best_split;
    });
    const uint32_t mid = static_cast<uint32_t>(it - refs.begin());
    return mid == begin || mid == end ? median(widest) : mid;
  }
};

}  // namespace

Bvh::Bvh(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles) {
  std::vector<PrimRef> refs;
  std::vector<Triangle> kept;
  std::vector<uint32_t> kept_ids;
  refs.reserve(triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    const glm::uvec3 tri = triangles[t];
    for (int k = 0; k < 3; ++k)
      SL_CHECK(tri[k] < positions.size(), "Bvh: triangle ", t, " has vertex index ", tri[k], " out of range [0, ",
               positions.size(), ")");
    const glm::vec3 p0 = positions[tri.x], p1 = positions[tri.y], p2 = positions[tri.z];
    const glm::vec3 n = glm::cross(p1 - p0, p2 - p0);
    // Zero-area and non-finite triangles can never be hit (det = 0 or NaN): leave them out.
    if (!std::isfinite(p0.x + p0.y + p0.z + p1.x + p1.y + p1.z + p2.x + p2.y + p2.z)) continue;
    if (n.x == 0.0f && n.y == 0.0f && n.z == 0.0f) continue;
    PrimRef r;
    r.box.extend(p0), r.box.extend(p1), r.box.extend(p2);
    r.centroid = r.box.centre();
    r.slot = static_cast<uint32_t>(kept.size());
    refs.push_back(r);
    kept.push_back({{p0.x, p0.y, p0.z}, {p1.x, p1.y, p1.z}, {p2.x, p2.y, p2.z}});
    kept_ids.push_back(static_cast<uint32_t>(t));
  }
  if (refs.empty()) return;

  Builder builder{refs};
  std::unique_ptr<BuildNode> root;
  if (omp_in_parallel()) {
    root = builder.build(0, static_cast<uint32_t>(refs.size()), 0);
  } else {
#pragma omp parallel
#pragma omp single
    root = builder.build(0, static_cast<uint32_t>(refs.size()), 0);
  }

  // Flatten depth-first: the first child follows its parent, so only the second needs an index.
  triangles_.resize(refs.size());
  ids_.resize(refs.size());
  for (size_t i = 0; i < refs.size(); ++i) {
    triangles_[i] = kept[refs[i].slot];
    ids_[i] = kept_ids[refs[i].slot];
  }
  nodes_.reserve(2 * refs.size());
  struct Item {
    const BuildNode* node;
    int64_t parent;  // flattened parent whose `offset` must point here, or -1
    int depth;
  };
  std::vector<Item> todo{{root.get(), -1, 1}};
  while (!todo.empty()) {
    const Item item = todo.back();
    todo.pop_back();
    const uint32_t index = static_cast<uint32_t>(nodes_.size());
    if (item.parent >= 0) nodes_[static_cast<size_t>(item.parent)].offset = index;
    const BuildNode& b = *item.node;
    BvhNode out{};
    for (int k = 0; k < 3; ++k) out.lo[k] = b.box.lo[k], out.hi[k] = b.box.hi[k];
    depth_ = std::max(depth_, item.depth);
    if (!b.child[0]) {
      // A leaf of more than 65535 identical-centroid triangles cannot occur: flat nodes split at
      // their median above kMaxLeafSize.
      out.offset = b.first;
      out.count = static_cast<uint16_t>(b.count);
      nodes_.push_back(out);
    } else {
      out.axis = static_cast<uint16_t>(b.axis);
      nodes_.push_back(out);
      todo.push_back({b.child[1].get(), index, item.depth + 1});  // popped after the whole first subtree
      todo.push_back({b.child[0].get(), -1, item.depth + 1});
    }
  }
  SL_CHECK(depth_ <= kMaxDepth, "Bvh: tree depth ", depth_, " exceeds ", kMaxDepth);
}

Bounds3 Bvh::bounds() const {
  Bounds3 b;
  if (!nodes_.empty()) {
    b.lo = glm::vec3(nodes_[0].lo[0], nodes_[0].lo[1], nodes_[0].lo[2]);
    b.hi = glm::vec3(nodes_[0].hi[0], nodes_[0].hi[1], nodes_[0].hi[2]);
  }
  return b;
}

template <bool kAnyHit>
Hit Bvh::traverse(const Ray& ray) const {
  Hit hit;
  if (nodes_.empty()) return hit;
  const PreparedRay r = prepare(ray);
  if (!r.valid) return hit;
  float tmax = ray.tmax;
  const BvhNode* nodes = nodes_.data();
  float tnear;
  if (!hit_box(nodes[0], r, tmax, tnear)) return hit;

  struct Entry {
    uint32_t node;
    float tnear;
  };
  Entry stack[kMaxDepth];
  int sp = 0;
  uint32_t current = 0;
  for (;;) {
    const BvhNode& n = nodes[current];
    if (n.count == 0) {
      // Ordered traversal: visit the nearer child first, defer the other with its entry distance.
      uint32_t a = current + 1, b = n.offset;
      float ta, tb;
      const bool ha = hit_box(nodes[a], r, tmax, ta), hb = hit_box(nodes[b], r, tmax, tb);
      if (ha && hb) {
        if (tb < ta) std::swap(a, b), std::swap(ta, tb);
        stack[sp++] = {b, tb};
        current = a;
        continue;
      }
      if (ha || hb) {
        current = ha ? a : b;
        continue;
      }
    } else {
      const Triangle* tri = triangles_.data() + n.offset;
      for (uint32_t i = 0; i < n.count; ++i) {
        float t, u, v;
        if (hit_triangle(r, tri[i], tmax, t, u, v)) {
          tmax = t;
          hit.t = t, hit.u = u, hit.v = v, hit.triangle = n.offset + i;
          if constexpr (kAnyHit) {
            hit.triangle = ids_[hit.triangle];
            return hit;
          }
        }
      }
    }
    for (;;) {
      if (sp == 0) {
        if (hit.hit()) hit.triangle = ids_[hit.triangle];
        return hit;
      }
      --sp;
      if (stack[sp].tnear <= tmax) {
        current = stack[sp].node;
        break;
      }
    }
  }
}

Hit Bvh::intersect(const Ray& ray) const { return traverse<false>(ray); }
bool Bvh::occluded(const Ray& ray) const { return traverse<true>(ray).hit(); }

void Bvh::intersect(const Ray* rays, Hit* hits, size_t count) const {
  const int64_t n = static_cast<int64_t>(count);
#pragma omp parallel for schedule(dynamic, 64)
  for (int64_t i = 0; i < n; ++i) hits[i] = traverse<false>(rays[i]);
}

void Bvh::occluded(const Ray* rays, uint8_t* occluded, size_t count) const {
  const int64_t n = static_cast<int64_t>(count);
#pragma omp parallel for schedule(dynamic, 64)
  for (int64_t i = 0; i < n; ++i) occluded[i] = traverse<true>(rays[i]).hit() ? 1 : 0;
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
    const Bvh::Triangle tri{{p0.x, p0.y, p0.z}, {p1.x, p1.y, p1.z}, {p2.x, p2.y, p2.z}};
    float th, u, v;
    if (hit_triangle(r, tri, tmax, th, u, v)) {
      tmax = th;
      hit.t = th, hit.u = u, hit.v = v, hit.triangle = static_cast<uint32_t>(i);
    }
  }
  return hit;
}

}  // namespace sl
