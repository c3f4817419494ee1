#include "nn/functional/conv_tuning.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <string>

namespace sl::nn::detail {
namespace {

// Size in bytes of the level-`level` data (or unified) cache of cpu0 from sysfs, 0 if unknown.
int64_t sysfs_cache(int level) {
  for (int i = 0; i < 8; ++i) {
    const std::string dir = "/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(i) + "/";
    std::ifstream lv(dir + "level"), ty(dir + "type"), sz(dir + "size");
    int l = 0;
    std::string type, size;
    if (!(lv >> l) || !(ty >> type) || !(sz >> size)) continue;
    if (l != level || type == "Instruction" || size.empty()) continue;
    int64_t v = std::atoll(size.c_str());
    if (size.back() == 'K') v <<= 10;
    if (size.back() == 'M') v <<= 20;
    return v;
  }
  return 0;
}

int64_t env_bytes(const char* name) {
  const char* s = std::getenv(name);
  return s ? std::atoll(s) : 0;
}

CacheSizes detect() {
  CacheSizes c;
  int64_t l1 = 0, l2 = 0;
#if defined(_SC_LEVEL1_DCACHE_SIZE) && defined(_SC_LEVEL2_CACHE_SIZE)
  l1 = sysconf(_SC_LEVEL1_DCACHE_SIZE);
  l2 = sysconf(_SC_LEVEL2_CACHE_SIZE);
#endif
  if (l1 <= 0) l1 = sysfs_cache(1);
  if (l2 <= 0) l2 = sysfs_cache(2);
  if (const int64_t e = env_bytes("STREETLIGHT_L1D_BYTES"); e > 0) l1 = e;
  if (const int64_t e = env_bytes("STREETLIGHT_L2_BYTES"); e > 0) l2 = e;
  // Implausible reports (a VM exposing 0 or a shared last level) fall back to the defaults.
  if (l1 >= (8 << 10) && l1 <= (1 << 20)) c.l1d = l1;
  if (l2 >= (128 << 10) && l2 <= (64 << 20)) c.l2 = l2;
  return c;
}

}  // namespace

const CacheSizes& cache_sizes() {
  static const CacheSizes sizes = detect();
  return sizes;
}

}  // namespace sl::nn::detail

namespace sl::nn::detail {

int64_t weight_grad_chunk() {
  // A quarter of L2 for one chunk's dyT rows of a 64-channel block (256 B per position).
  const int64_t chunk = cache_sizes().l2 / 4 / 256;
  return std::clamp<int64_t>(chunk / 16 * 16, 256, 4096);
}

}  // namespace sl::nn::detail
