// util/check.h: a broken internal invariant is reported apart from bad input.
#include <gtest/gtest.h>

#include <vector>

#include "util/check.h"
#include "util/error.h"

namespace sl::test {
namespace {

int twice(int x) {
  SL_ASSERT(x >= 0, "twice of ", x);
  return 2 * x;
}

TEST(InternalCheck, PassingChecksCostNothingVisible) {
  SL_ASSERT_EQ(twice(2), 4, "arithmetic");
  SL_DASSERT(twice(1) == 2, "arithmetic");
  EXPECT_EQ(twice(3), 6);
}

TEST(InternalCheckDeathTest, FailedAssertExitsWithTheInternalErrorCodeAndNamesTheCondition) {
  EXPECT_EXIT(twice(-1), ::testing::ExitedWithCode(kInternalErrorExit),
              "internal error: .*check_test.cpp:[0-9]+: check `x >= 0` failed: twice of -1");
}

TEST(InternalCheckDeathTest, FailedAssertEqPrintsBothValues) {
  const std::vector<int> grads(3), inputs(2);
  EXPECT_EXIT(SL_ASSERT_EQ(grads.size(), inputs.size(), "backward of op"),
              ::testing::ExitedWithCode(kInternalErrorExit), "check `grads.size\\(\\) == inputs.size\\(\\)` failed: 3 != 2");
}

TEST(InternalCheck, TheInternalErrorCodeIsNotTheBadInputCode) {
  EXPECT_NE(kInternalErrorExit, 2);
  EXPECT_NE(kInternalErrorExit, 1);
  EXPECT_THROW(SL_CHECK(false, "bad input"), Error);  // input errors stay exceptions (exit 2 in tools)
}

#ifdef NDEBUG
TEST(InternalCheck, DebugOnlyChecksAreCompiledOutInRelease) {
  int evaluated = 0;
  SL_DASSERT(++evaluated < 0, "never evaluated");
  EXPECT_EQ(evaluated, 0);
}
#else
TEST(InternalCheckDeathTest, DebugOnlyChecksFireInDebug) {
  EXPECT_EXIT(SL_DASSERT(1 + 1 == 3, "debug"), ::testing::ExitedWithCode(kInternalErrorExit), "1 \\+ 1 == 3");
}
#endif

}  // namespace
}  // namespace sl::test
