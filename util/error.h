// Error reporting shared by every part of Streetlight.
//
// Contract: bad input throws sl::Error (a std::runtime_error) whose message names the op, file,
// key or argument and the offending value or shape. Nothing in the library aborts on bad input.
// Executables catch sl::Error, print one line `error: <message>` and exit 2 (docs/DESIGN.md, "Shared conventions").
#pragma once
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace sl {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Concatenates any streamable values into one string: cat("conv2d: got ", 3, " dims").
template <class... Args>
std::string cat(const Args&... args) {
  std::ostringstream os;
  (os << ... << args);
  return os.str();
}

template <class... Args>
[[noreturn]] void fail(const Args&... args) {
  throw Error(cat(args...));
}

// "[2, 3, 4]"
std::string shape_str(const std::vector<int64_t>& shape);

}  // namespace sl

#define SL_CHECK(cond, ...)              \
  do {                                   \
    if (!(cond)) ::sl::fail(__VA_ARGS__); \
  } while (0)
