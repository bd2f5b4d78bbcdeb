// Which failures are a resource that ran out rather than bad input: the same work may then
// succeed with less (a shot's frame with fewer neighbours) or in a new process. Decided once,
// from the exception where it is caught, and carried as a value from there on (ReadResult,
// FrameResult, the worker's response), never recognised again from a message's text.
#pragma once

#include <exception>

namespace ssdo {

enum class ResourceFailure {
  none,
  memory,  // an allocation failed (e.g. under the worker's --memory-limit)
  thread,  // a thread could not start (its stack is address space too)
};

// What `e` reports:
// - memory: std::bad_alloc; OpenCV's cv::Exception with code StsNoMem; an exception of a
//   library that rethrows an allocation failure as its own type with the original's text
//   (OpenEXR's pool: "std::bad_alloc"; OpenCV's "Insufficient memory").
// - thread: std::system_error with errc::resource_unavailable_try_again (std::thread), or a
//   library's exception carrying that error's text.
// - none otherwise.
ResourceFailure resource_failure(const std::exception& e);

}  // namespace ssdo
