// Placeholder until the method lands: refuses to run rather than return a fake result.
#include "kernels/ao_methods.h"

namespace ssdo::detail {

void ao_gtao(const AoInputs&, const AoSettings&, AoOutput&, const cv::Rect&, int) {
  CV_Error(cv::Error::StsNotImplemented, "AO method 'gtao' is not implemented yet");
}

}  // namespace ssdo::detail
