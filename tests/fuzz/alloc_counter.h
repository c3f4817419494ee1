// Peak heap use of a block of code, for the memory-bound tests of issue 17.
//
// alloc_counter.cpp interposes malloc, calloc, realloc, free and the aligned allocators of the
// test executable (forwarding to glibc's __libc_* entry points), so every allocation counts:
// operator new, std::aligned_alloc (Tensor storage) and the C libraries under OpenImageIO.
// Live bytes are malloc_usable_size of each block. Unavailable under ASan (which owns malloc):
// available() is then false and tests skip.
#pragma once
#include <cstddef>

namespace sl::test {

bool alloc_counter_available();
// Starts a measurement: the peak is reset to the current live bytes.
void reset_peak();
// Peak live heap bytes since reset_peak(), minus the live bytes at reset_peak().
size_t peak_since_reset();

}  // namespace sl::test
