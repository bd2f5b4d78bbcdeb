#pragma once

namespace ssdo {
// The product's version, as printed by `ssdo --version`.
const char* version_string();
}  // namespace ssdo
