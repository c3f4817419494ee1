// glTF 2.0 import (.glb and .gltf) into one flattened world-space Mesh.
//
// Requires: a glTF 2.0 file whose meshes are triangle lists, strips or fans with float32
// POSITION. Guarantees: the default scene (or scene 0, or every root node when the file has no
// scenes) is walked from its roots; each node's transform (matrix, or T·R·S) is composed down
// the hierarchy and applied to positions (and its inverse transpose to normals; winding flips
// under a mirroring transform so faces keep their outward side). All primitives land in one
// Mesh with one material per glTF material plus a default material for primitives without
// one. Missing normals are computed from faces; missing UVs are zero. Base-colour textures
// are decoded to linear float (sRGB transfer removed). The returned Mesh passes validate().
// Throws: sl::Error naming the file and the unsupported or broken item for
// KHR_draco_mesh_compression, EXT_meshopt_compression, point/line primitives, sparse or
// out-of-bounds accessors, missing or truncated buffers, out-of-range indices, non-finite
// positions, node cycles, and any parse failure. It never crashes on a damaged file.
#pragma once
#include <string>

#include "render/mesh.h"

namespace sl::render {

Mesh load_gltf(const std::string& path);

}  // namespace sl::render
