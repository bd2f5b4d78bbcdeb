# Finds the two OpenCV modules ssdo uses, core (every layer's images) and imgproc (the
# kernels' distance transform, kernels/thickness.cpp). Debian's libopencv-core-dev and
# libopencv-imgproc-dev ship their headers and libraries but not OpenCVConfig.cmake (that
# comes with the full libopencv-dev). Defines the imported targets OpenCV::core and
# OpenCV::imgproc.
find_path(OpenCVModules_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
find_path(OpenCVModules_IMGPROC_INCLUDE_DIR opencv2/imgproc.hpp PATH_SUFFIXES opencv4)
find_library(OpenCVModules_CORE_LIBRARY NAMES opencv_core)
find_library(OpenCVModules_IMGPROC_LIBRARY NAMES opencv_imgproc)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenCVModules REQUIRED_VARS OpenCVModules_CORE_LIBRARY
  OpenCVModules_IMGPROC_LIBRARY OpenCVModules_INCLUDE_DIR OpenCVModules_IMGPROC_INCLUDE_DIR)
if(OpenCVModules_FOUND AND NOT TARGET OpenCV::core)
  add_library(OpenCV::core UNKNOWN IMPORTED)
  set_target_properties(OpenCV::core PROPERTIES
    IMPORTED_LOCATION "${OpenCVModules_CORE_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCVModules_INCLUDE_DIR}")
  add_library(OpenCV::imgproc UNKNOWN IMPORTED)
  set_target_properties(OpenCV::imgproc PROPERTIES
    IMPORTED_LOCATION "${OpenCVModules_IMGPROC_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCVModules_IMGPROC_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES OpenCV::core)
endif()
mark_as_advanced(OpenCVModules_INCLUDE_DIR OpenCVModules_IMGPROC_INCLUDE_DIR OpenCVModules_CORE_LIBRARY
  OpenCVModules_IMGPROC_LIBRARY)
