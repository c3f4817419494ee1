// libFuzzer entry point of one harness; STREETLIGHT_FUZZ_TARGET names it (CMakeLists.txt).
#include "tests/fuzz/harness/fuzz_harness.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sl::fuzz::STREETLIGHT_FUZZ_TARGET(data, size);
  return 0;
}

// Leaks inside third-party code that we cannot fix, matched by the allocating frame:
// - OpenImageIO 2.4's PNG read callback builds an error string and then libpng longjmps out of
//   the callback on truncated data, skipping the string's destructor (31 bytes per bad PNG).
extern "C" const char* __lsan_default_suppressions() {
  return "leak:OpenImageIO_v2_4::PNGInput::PngReadCallback\n";
}
