// Template definitions of fuzz_harness.h.
#pragma once
#include <exception>

#include "util/error.h"

namespace sl::test {

template <class F>
bool refuses_cleanly_or_runs(const char* target, F&& f) {
  try {
    f();
    return true;
  } catch (const sl::Error&) {
    return false;
  } catch (const std::exception& e) {
    violation(target, std::string("escaped as a non-sl::Error exception: ") + e.what());
  } catch (...) {
    violation(target, "escaped as an unknown exception");
  }
}

}  // namespace sl::test
