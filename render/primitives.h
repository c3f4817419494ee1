// Procedural meshes for tests, benchmarks and analytic scenes: icosphere, ground plane, box.
//
// Contract: each function returns a Mesh that passes validate(), with per-vertex unit normals
// pointing outwards (counter-clockwise winding seen from outside), per-vertex UVs, one
// material (the one given) and every triangle's material id 0. Sizes are in metres.
// Throws sl::Error naming the argument for a negative or non-finite size, or subdivisions
// outside [0, 7] (level 7 is already 327 680 triangles).
#pragma once
#include "render/mesh.h"

namespace sl::render {

// Geodesic sphere: an icosahedron subdivided `subdivisions` times (20·4^s triangles), vertices
// projected onto the sphere, so normals are exact (position − centre) / radius.
Mesh make_icosphere(const glm::vec3& centre, float radius, int subdivisions, const Material& material = {});

// Square in the plane y = height, facing +Y, side `size_m`, centred on (centre_x, centre_z).
Mesh make_ground_plane(float size_m, float height = 0.0f, const Material& material = {},
                       float centre_x = 0.0f, float centre_z = 0.0f);

// Axis-aligned box with flat-shaded faces (24 vertices, 12 triangles).
Mesh make_box(const glm::vec3& lo, const glm::vec3& hi, const Material& material = {});

}  // namespace sl::render
