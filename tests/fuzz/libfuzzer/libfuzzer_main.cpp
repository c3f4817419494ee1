// libFuzzer entry point of one harness; STREETLIGHT_FUZZ_TARGET names it (CMakeLists.txt).
#include "tests/fuzz/harness/fuzz_harness.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sl::fuzz::STREETLIGHT_FUZZ_TARGET(data, size);
  return 0;
}
