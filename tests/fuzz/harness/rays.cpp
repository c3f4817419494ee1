// Harness: render/ray_file.h read_ray_file (streetlight-bench trace --rays).
// Invariant: size/24 rays, every origin and direction finite.
#include <cmath>

#include "render/ray_file.h"
#include "tests/fuzz/harness/fuzz_harness.h"

using sl::render::Ray;
using sl::render::read_ray_file;

namespace sl::test {

void fuzz_rays(const uint8_t* data, size_t size) {
  const std::string path = write_scratch("rays.bin", data, size);
  refuses_cleanly_or_runs("rays", [&] {
    const std::vector<Ray> rays = read_ray_file(path);
    if (rays.size() * 24 != size) violation("rays", "wrong ray count");
    for (const Ray& r : rays)
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(r.origin[k]) || !std::isfinite(r.direction[k])) violation("rays", "non-finite ray");
  });
}

}  // namespace sl::test
