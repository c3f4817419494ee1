// libFuzzer entry point of one harness; STREETLIGHT_FUZZ_TARGET names it (CMakeLists.txt).
#include "tests/fuzz/harness/fuzz_harness.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sl::test::STREETLIGHT_FUZZ_TARGET(data, size);
  return 0;
}

// Leaks inside third-party code that we cannot fix, matched by a frame of the allocation stack:
// - OpenImageIO 2.4's PNG read callback copies an error string (ImageInput::geterror) and then
//   libpng longjmps out of the callback on truncated data, skipping the string's destructor
//   (31 bytes per bad PNG). The fast unwinder stops inside OpenImageIO (no frame pointers), so
//   the recorded stack ends at geterror, not at the callback.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:OpenImageIO_v2_4::ImageInput::geterror\n";
}
