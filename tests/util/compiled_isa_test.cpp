// The build compiles the SIMD path that its STREETLIGHT_ARCH asks for (scripts/test_simd_paths.sh
// relies on this to know which kernels a run of the suite has tested).
#include <gtest/gtest.h>

#include <string>

#include "util/compiled_isa.h"

namespace sl::test {

namespace {

// The widest path this CPU can run, as -march=native would pick it.
std::string widest_isa_of_this_cpu() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f")) return "avx512";
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "avx2";
  return "scalar";
}

}  // namespace

TEST(CompiledIsa, IsThePathThisBuildsArchSelects) {
  const std::string arch = STREETLIGHT_ARCH;
  std::string expected;
  if (arch == "native")
    expected = widest_isa_of_this_cpu();
  else if (arch == "x86-64-v4")
    expected = "avx512";
  else if (arch == "x86-64-v3")
    expected = "avx2";
  else if (arch == "x86-64-v2")
    expected = "scalar";
  else
    GTEST_SKIP() << "STREETLIGHT_ARCH '" << arch << "' (STREETLIGHT_NATIVE=OFF builds pass their own flags)";
  EXPECT_EQ(std::string(compiled_isa()), expected) << "STREETLIGHT_ARCH=" << arch;
  RecordProperty("compiled_isa", compiled_isa());
}

}  // namespace sl::test
