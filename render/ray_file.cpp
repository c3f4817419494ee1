#include "render/ray_file.h"

#include <cmath>
#include <fstream>

#include "util/error.h"

namespace sl::render {

std::vector<Ray> read_ray_file(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  SL_CHECK(in.good(), what, ": cannot open '", path, "'");
  const std::streamoff size = in.tellg();
  SL_CHECK(size > 0 && size % 24 == 0, what, " '", path, "' has ", size,
           " bytes, expected a positive multiple of 24 (6 float32 per ray)");
  std::vector<float> raw(static_cast<size_t>(size) / 4);
  in.seekg(0);
  in.read(reinterpret_cast<char*>(raw.data()), size);
  SL_CHECK(in.good(), what, ": cannot read '", path, "'");
  std::vector<Ray> rays(raw.size() / 6);
  for (size_t i = 0; i < rays.size(); ++i) {
    const float* p = &raw[6 * i];
    for (int k = 0; k < 6; ++k)
      SL_CHECK(std::isfinite(p[k]), what, " '", path, "' ray ", i, " has a non-finite value ", p[k]);
    rays[i].origin = {p[0], p[1], p[2]};
    rays[i].direction = {p[3], p[4], p[5]};
  }
  return rays;
}

}  // namespace sl::render
