// Which exceptions are a resource running out (core/resource_failure.h): decided from the
// exception's type and code, and from a wrapped exception's text only where that text is
// the original's, never from words a file name may hold.
#include "core/resource_failure.h"

#include <new>
#include <stdexcept>
#include <system_error>

#include <opencv2/core.hpp>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

TEST(ResourceFailure, AllocationFailuresAreMemory) {
  EXPECT_EQ(resource_failure(std::bad_alloc()), ResourceFailure::memory);
  EXPECT_EQ(resource_failure(std::bad_array_new_length()), ResourceFailure::memory);
  EXPECT_EQ(resource_failure(cv::Exception(cv::Error::StsNoMem, "Failed to allocate 8 bytes", "f", "file", 1)),
            ResourceFailure::memory);
  // OpenEXR's pool rethrows what a decoding task threw with the text of the original.
  EXPECT_EQ(resource_failure(std::runtime_error("Error reading pixel data from image file \"a.exr\". std::bad_alloc")),
            ResourceFailure::memory);
}

TEST(ResourceFailure, ThreadsThatCannotStartAreThreads) {
  EXPECT_EQ(resource_failure(std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again))),
            ResourceFailure::thread);
  EXPECT_EQ(resource_failure(std::runtime_error("cannot start a thread: Resource temporarily unavailable")),
            ResourceFailure::thread);
}

TEST(ResourceFailure, OtherFailuresAreNoneWhatTheirTextSays) {
  EXPECT_EQ(resource_failure(cv::Exception(cv::Error::StsBadArg, "Insufficient memory? no: a bad argument", "f",
                                           "file", 1)),
            ResourceFailure::none);
  EXPECT_EQ(resource_failure(std::system_error(std::make_error_code(std::errc::no_such_file_or_directory))),
            ResourceFailure::none);
  EXPECT_EQ(resource_failure(std::runtime_error("/frames/out of memory.exr: damaged or truncated file")),
            ResourceFailure::none);
  EXPECT_EQ(resource_failure(std::runtime_error("bad_alloc.exr: not an OpenEXR file")), ResourceFailure::none);
  EXPECT_EQ(resource_failure(std::logic_error("")), ResourceFailure::none);
}

}  // namespace
}  // namespace ssdo
