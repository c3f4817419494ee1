// Internal invariants: checks that mark a bug in Streetlight, kept apart from bad input.
//
// Bad input (a user's file, flag or shape) raises sl::Error (util/error.h): executables print
// `error: ...` and exit 2. A broken internal invariant is not the user's mistake, so it is not
// an exception a caller could mistake for bad input: SL_ASSERT and SL_ASSERT_EQ print
// `internal error: FILE:LINE: ...` with the failed condition (SL_ASSERT_EQ: both values) and
// a message to stderr, and end the process with kInternalErrorExit (70, EX_SOFTWARE of
// sysexits.h) — never 2, never an abort or a core dump. SL_DASSERT / SL_DASSERT_EQ are the same
// checks for hot loops, compiled only without NDEBUG (Debug builds and the sanitizer build).
#pragma once
#include <cstdio>
#include <cstdlib>
#include <string>

#include "util/error.h"

namespace sl {

inline constexpr int kInternalErrorExit = 70;

[[noreturn]] inline void internal_error(const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "internal error: %s:%d: %s (a bug in Streetlight, not in the input)\n", file, line,
               what.c_str());
  std::fflush(stderr);
  std::exit(kInternalErrorExit);
}

}  // namespace sl

#define SL_ASSERT(cond, ...)                                                                    \
  do {                                                                                          \
    if (!(cond)) ::sl::internal_error(__FILE__, __LINE__, ::sl::cat("check `" #cond "` failed: ", __VA_ARGS__)); \
  } while (0)

#define SL_ASSERT_EQ(a, b, ...)                                                                 \
  do {                                                                                          \
    const auto& sl_assert_a_ = (a);                                                             \
    const auto& sl_assert_b_ = (b);                                                             \
    if (!(sl_assert_a_ == sl_assert_b_))                                                        \
      ::sl::internal_error(__FILE__, __LINE__,                                                  \
                           ::sl::cat("check `" #a " == " #b "` failed: ", sl_assert_a_, " != ", sl_assert_b_, \
                                     ": ", __VA_ARGS__));                                       \
  } while (0)

#ifdef NDEBUG
#define SL_DASSERT(cond, ...) \
  do {                        \
  } while (0)
#define SL_DASSERT_EQ(a, b, ...) \
  do {                           \
  } while (0)
#else
#define SL_DASSERT(cond, ...) SL_ASSERT(cond, __VA_ARGS__)
#define SL_DASSERT_EQ(a, b, ...) SL_ASSERT_EQ(a, b, __VA_ARGS__)
#endif
