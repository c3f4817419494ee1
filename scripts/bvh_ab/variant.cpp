// One render/bvh variant behind a C interface, for scripts/bvh_ab.sh. Compiled once per variant
// with -Dsl=slA or -Dsl=slB (so two versions of the library link into one program) and
// -DPFX(n)=A_##n or B_##n. The rays are converted to Ray once, outside the timed calls.
#include <cstdint>
#include <vector>

#include "render/bvh.h"

using namespace sl::render;

extern "C" void* PFX(build)(const float* pos, size_t npos, const unsigned* tri, size_t ntri) {
  std::vector<glm::vec3> p(npos);
  std::vector<glm::uvec3> t(ntri);
  for (size_t i = 0; i < npos; ++i) p[i] = {pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]};
  for (size_t i = 0; i < ntri; ++i) t[i] = {tri[3 * i], tri[3 * i + 1], tri[3 * i + 2]};
  return new Bvh(p, t);
}

// Closest hit (t, triangle) or any hit (triangle = 0/1) of every ray; outputs may be null.
extern "C" void PFX(trace)(void* b, const float* rays, size_t n, float* t_out, unsigned* id_out, int any) {
  static std::vector<Ray> rs;
  static std::vector<Hit> hs;
  static std::vector<uint8_t> oc;
  static const float* cached = nullptr;
  if (cached != rays || rs.size() != n) {
    cached = rays, rs.resize(n), hs.resize(n), oc.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const float* q = rays + 6 * i;
      rs[i].origin = {q[0], q[1], q[2]}, rs[i].direction = {q[3], q[4], q[5]}, rs[i].tmin = 0.0f;
    }
  }
  const Bvh& bvh = *static_cast<const Bvh*>(b);
  if (any) {
    bvh.occluded(rs.data(), oc.data(), n);
    if (id_out)
      for (size_t i = 0; i < n; ++i) id_out[i] = oc[i];
  } else {
    bvh.intersect(rs.data(), hs.data(), n);
    if (t_out)
      for (size_t i = 0; i < n; ++i) t_out[i] = hs[i].t, id_out[i] = hs[i].triangle;
  }
}
