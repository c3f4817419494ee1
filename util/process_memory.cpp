#include "util/process_memory.h"

#include <fstream>

#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace sl {

int64_t resident_bytes() {
  std::ifstream f("/proc/self/statm");
  int64_t size_pages = 0, resident_pages = 0;
  if (!(f >> size_pages >> resident_pages)) return 0;
  const long page = sysconf(_SC_PAGESIZE);
  return page > 0 ? resident_pages * int64_t(page) : 0;
}

void release_free_heap() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace sl
