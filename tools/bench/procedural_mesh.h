// Procedural meshes for the BVH benchmark set (streetlight-bench gen-mesh --kind ...).
//
// Every mesh is a pure function of (kind, triangles, seed): the same arguments give the same
// vertices, bit for bit, on any machine and thread count. `triangles` is a target: the result
// has at least that many triangles; machine and facade add whole parts until it is reached, so
// they overshoot by at most one part (a few hundred triangles; for facade one building, up to
// about 40k). Units are metres, +Y up.
//   machine: CAD-like: hundreds to thousands of small disjoint parts (boxes, cylinders, bolt
//            rings, tubes) of log-uniformly varied scale on a jittered grid, on a base plate.
//   facade:  architecture: rows of buildings along streets, walls with window openings (reveals,
//            frames, mullions, glass, sills), floor slabs, balconies with thin railings, roofs and
//            a large ground plane: large and tiny triangles side by side, thin walls.
//   blob:    organic / scanned-like: a cube-sphere with near-uniform triangles, displaced by
//            domain-warped fractal value noise (fine detail at every scale).
//   foliage: thin slivers (aspect ratio 20-200), randomly oriented and overlapping, in clumps
//            inside a few tree crowns above a ground plane.
//   terrain: a fractal heightfield (2 triangles per grid cell), e.g. for a mesh over 1M triangles.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "render/mesh.h"

namespace sl::bench {

const std::vector<std::string>& procedural_mesh_kinds();
// Throws sl::Error for an unknown kind.
render::Mesh procedural_mesh(const std::string& kind, int64_t triangles, uint64_t seed);

}  // namespace sl::bench
