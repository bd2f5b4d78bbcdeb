#include "service/version.h"

namespace ssdo {
const char* version_string() { return "ssdo 0.1.0"; }
}  // namespace ssdo
