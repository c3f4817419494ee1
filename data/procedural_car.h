// A procedural car-like object, so object insertion needs no shared data: a body box, a
// cabin with dark glass, and four wheel cylinders, about 4.5 × 1.8 × 1.5 m.
//
// Frame (the object frame of data/object_placement.h): metres, +Y up, the bottom of the wheels
// on y = 0, the footprint centred on the origin, the length along +X (the car's forward
// direction, as KITTI's rotation_y assumes), the width along Z.
// Materials are glTF metallic-roughness (mapped onto the Disney BRDF by the renderers): a
// glossy clear-coated paint of the given colour, glass, rubber, and grey trim.
// Guarantees: a Mesh that passes validate(), a few hundred triangles, outward normals.
// Throws: sl::Error when a dimension is not finite and positive or a colour channel is outside
// [0, 1], naming the field.
#pragma once
#include <glm/glm.hpp>

#include "render/mesh.h"

namespace sl::data {

struct ProceduralCarParams {
  double length_m = 4.5, width_m = 1.8, height_m = 1.5;
  glm::vec3 paint_rgb{0.55f, 0.05f, 0.04f};  // linear base colour of the paint
  int wheel_segments = 12;                   // facets around each wheel (>= 6)
};

render::Mesh make_procedural_car(const ProceduralCarParams& params = {});

// A closed cylinder along +Z from z0 to z1 (flat-shaded caps, smooth sides), used for wheels.
render::Mesh make_cylinder_z(const glm::vec3& centre_at_z0, float radius, float length, int segments,
                             const render::Material& material);

}  // namespace sl::data
