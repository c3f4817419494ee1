// Embree 3 (rtcIntersect1 / rtcOccluded1) as variant B of scripts/bvh_ab.sh --embree.
#include <embree3/rtcore.h>

#include <cstddef>
#include <limits>
#include <vector>

struct Scene {
  RTCDevice device;
  RTCScene scene;
};

extern "C" void* B_build(const float* pos, size_t npos, const unsigned* tri, size_t ntri) {
  Scene* s = new Scene{rtcNewDevice(nullptr), nullptr};
  s->scene = rtcNewScene(s->device);
  RTCGeometry g = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, npos));
  for (size_t i = 0; i < 3 * npos; ++i) vb[i] = pos[i];
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, ntri));
  for (size_t i = 0; i < 3 * ntri; ++i) ib[i] = tri[i];
  rtcCommitGeometry(g), rtcAttachGeometry(s->scene, g), rtcReleaseGeometry(g), rtcCommitScene(s->scene);
  return s;
}

extern "C" void B_trace(void* p, const float* rays, size_t n, float* t_out, unsigned* id_out, int any) {
  static std::vector<float> t_tmp;
  static std::vector<unsigned> id_tmp;
  t_tmp.resize(n), id_tmp.resize(n);
  if (!t_out) t_out = t_tmp.data();
  if (!id_out) id_out = id_tmp.data();
  const Scene* s = static_cast<const Scene*>(p);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  constexpr float kInf = std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < n; ++i) {
    const float* q = rays + 6 * i;
    RTCRayHit rh;
    rh.ray.org_x = q[0], rh.ray.org_y = q[1], rh.ray.org_z = q[2];
    rh.ray.dir_x = q[3], rh.ray.dir_y = q[4], rh.ray.dir_z = q[5];
    rh.ray.tnear = 0.0f, rh.ray.tfar = kInf, rh.ray.time = 0.0f, rh.ray.mask = ~0u, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID, rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    if (any) {
      rtcOccluded1(s->scene, &ctx, &rh.ray);
      id_out[i] = rh.ray.tfar < 0.0f;
    } else {
      rtcIntersect1(s->scene, &ctx, &rh);
      const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      t_out[i] = hit ? rh.ray.tfar : kInf, id_out[i] = hit ? rh.hit.primID : ~0u;
    }
  }
}
