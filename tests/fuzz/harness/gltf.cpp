// Harness: render/gltf_loader.h load_gltf, our importer on top of tinygltf. Inputs starting with
// the GLB magic are written as .glb, all others as .gltf.
// Invariant: a returned Mesh passes Mesh::validate().
#include <cstring>

#include "render/gltf_loader.h"
#include "tests/fuzz/harness/fuzz_harness.h"

using sl::render::load_gltf;
using sl::render::Mesh;

namespace sl::test {

void fuzz_gltf(const uint8_t* data, size_t size) {
  const bool glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::string path = write_scratch(glb ? "input.glb" : "input.gltf", data, size);
  refuses_cleanly_or_runs("gltf", [&] {
    const Mesh mesh = load_gltf(path);
    try {
      mesh.validate("fuzz");
    } catch (const Error& e) {
      violation("gltf", std::string("load_gltf returned a mesh that fails validate(): ") + e.what());
    }
  });
}

}  // namespace sl::test
