// STREETLIGHT_ADDRESS_SANITIZER is defined when the build uses AddressSanitizer (GCC's
// __SANITIZE_ADDRESS__ or clang's __has_feature): its allocator replaces the C library's, so tests
// that count or trim the C library's heap skip or step aside.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define STREETLIGHT_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STREETLIGHT_ADDRESS_SANITIZER 1
#endif
#endif
