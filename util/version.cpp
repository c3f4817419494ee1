#include "util/version.h"

namespace sl {

const char* version() { return STREETLIGHT_VERSION; }

}  // namespace sl
