// The release this build belongs to (CHANGELOG.md), as "MAJOR.MINOR.PATCH".
//
// Contract: version() is the project version of the top-level CMakeLists.txt, the one
// `streetlight-<tool> --version` prints and `streetlight.__version__` holds. It never throws.
#pragma once

namespace sl {

const char* version();

}  // namespace sl
