#include "core/resource_failure.h"

#include <cstring>
#include <new>
#include <system_error>

#include <opencv2/core.hpp>

namespace ssdo {

ResourceFailure resource_failure(const std::exception& e) {
  if (dynamic_cast<const std::bad_alloc*>(&e) != nullptr) return ResourceFailure::memory;
  if (const auto* cv_error = dynamic_cast<const cv::Exception*>(&e))
    return cv_error->code == cv::Error::StsNoMem ? ResourceFailure::memory : ResourceFailure::none;
  if (const auto* system = dynamic_cast<const std::system_error*>(&e))
    return system->code() == std::errc::resource_unavailable_try_again ? ResourceFailure::thread
                                                                        : ResourceFailure::none;
  // Another library's exception around one of the above keeps only its text: the whole
  // what() of std::bad_alloc, OpenCV's name of StsNoMem, and strerror(EAGAIN).
  if (std::strstr(e.what(), "std::bad_alloc") != nullptr || std::strstr(e.what(), "Insufficient memory") != nullptr)
    return ResourceFailure::memory;
  if (std::strstr(e.what(), "Resource temporarily unavailable") != nullptr) return ResourceFailure::thread;
  return ResourceFailure::none;
}

}  // namespace ssdo
