// scripts/bvh_ab.sh's driver: builds variants A and B over one mesh and traces the same rays with
// each, alternating A,B / B,A pass by pass on this one thread. Prints the throughput from the
// least thread-CPU time of each (a loaded machine only adds time), the median over passes of the
// per-pass ratio B/A, and how many rays' hits differ (bit for bit).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <string>
#include <vector>

#include "render/gltf_loader.h"

extern "C" void* A_build(const float*, size_t, const unsigned*, size_t);
extern "C" void A_trace(void*, const float*, size_t, float*, unsigned*, int);
extern "C" void* B_build(const float*, size_t, const unsigned*, size_t);
extern "C" void B_trace(void*, const float*, size_t, float*, unsigned*, int);

static double cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bvh_ab MESH.glb RAYS.bin PASSES\n");
    return 2;
  }
  const sl::render::Mesh mesh = sl::render::load_gltf(argv[1]);
  std::ifstream in(argv[2], std::ios::binary | std::ios::ate);
  const size_t bytes = static_cast<size_t>(in.tellg());
  in.seekg(0);
  std::vector<float> rays(bytes / 4);
  in.read(reinterpret_cast<char*>(rays.data()), static_cast<std::streamsize>(bytes));
  const size_t n = rays.size() / 6;
  const int passes = std::max(1, std::atoi(argv[3]));
  std::vector<float> pos;
  for (const auto& p : mesh.positions) pos.insert(pos.end(), {p.x, p.y, p.z});
  std::vector<unsigned> tri;
  for (const auto& t : mesh.triangles) tri.insert(tri.end(), {t.x, t.y, t.z});
  void* a = A_build(pos.data(), mesh.positions.size(), tri.data(), mesh.triangles.size());
  void* b = B_build(pos.data(), mesh.positions.size(), tri.data(), mesh.triangles.size());
  A_trace(a, rays.data(), n, nullptr, nullptr, 0), B_trace(b, rays.data(), n, nullptr, nullptr, 0);  // warm-up
  std::vector<float> ta(n), tb(n);
  std::vector<unsigned> ia(n), ib(n);
  for (int any = 0; any < 2; ++any) {
    std::vector<double> da, db, ratio;
    for (int p = 0; p < passes; ++p) {
      double x = 0, y = 0;
      for (int k = 0; k < 2; ++k) {
        const bool run_a = (k == 0) == (p % 2 == 0);
        const double s = cpu_ms();
        run_a ? A_trace(a, rays.data(), n, nullptr, nullptr, any) : B_trace(b, rays.data(), n, nullptr, nullptr, any);
        (run_a ? x : y) = cpu_ms() - s;
      }
      da.push_back(x), db.push_back(y), ratio.push_back(x / y);
    }
    A_trace(a, rays.data(), n, ta.data(), ia.data(), any), B_trace(b, rays.data(), n, tb.data(), ib.data(), any);
    size_t diff = 0;
    for (size_t i = 0; i < n; ++i) diff += any ? ia[i] != ib[i] : std::memcmp(&ta[i], &tb[i], 4) != 0 || ia[i] != ib[i];
    std::sort(ratio.begin(), ratio.end());
    const double ma = *std::min_element(da.begin(), da.end()), mb = *std::min_element(db.begin(), db.end());
    std::printf("%s %.3f %.3f %.4f %zu\n", any ? "any" : "closest", n / ma / 1e3, n / mb / 1e3, ratio[ratio.size() / 2], diff);
  }
  return 0;
}
