// c^n for an integer n in [0, 256] by squaring from the most significant bit, for any type
// with * (a float, or a vector of floats): one association, so a scalar and a vector lane
// give the same bits. `one` is the type's 1. The normal lobes of the denoise and the
// temporal filter (max(0, n . n_tap)^normal_power): a runtime std::pow per tap costs more
// than the rest of their weights together.
#pragma once

namespace ssdo {

template <class T>
inline T integer_power(T c, unsigned n, T one) {
  T r = one;
  for (int bit = 8; bit >= 0; --bit) {  // n <= 256 = 2^8
    r = r * r;
    if ((n >> bit) & 1u) r = r * c;
  }
  return r;
}

}  // namespace ssdo
