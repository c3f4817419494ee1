// glTF 2.0 binary (.glb) export of a Mesh.
//
// Requires: a Mesh that passes validate(). Guarantees: one node, one glTF mesh, and one
// primitive per material that has triangles; shared POSITION and NORMAL (and TEXCOORD_0 when
// the mesh has UVs) accessors, uint32 indices; materials keep base-colour factor, metallic,
// roughness and KHR_materials_clearcoat (textures are not written). Loading the file with
// load_gltf gives back the same positions and triangles, grouped by material. The file is
// written to a temporary name and renamed, so a failure never leaves a partial file.
// Throws: sl::Error naming the path when the mesh is invalid or the file cannot be written.
#pragma once
#include <string>

#include "render/mesh.h"

namespace sl::render {

void write_glb(const Mesh& mesh, const std::string& path);

}  // namespace sl::render
