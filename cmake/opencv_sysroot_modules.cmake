# OpenCV's modules as imported targets from a cross sysroot's libraries and headers. Debian's
# OpenCV CMake configuration lives in libopencv-dev, which depends on every module (VTK, Qt, MPI
# for arm64 too) and checks that each of their libraries exists; the sysroot holds only the
# modules calbox links, so the cross build names them itself, as the configuration would.
find_path(CALBOX_OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
set(OpenCV_LIBS "")
foreach(module ${CALBOX_OPENCV_MODULES})
  find_library(CALBOX_OPENCV_${module}_LIBRARY opencv_${module} REQUIRED)
  add_library(opencv_${module} SHARED IMPORTED)
  set_target_properties(opencv_${module} PROPERTIES
    IMPORTED_LOCATION "${CALBOX_OPENCV_${module}_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CALBOX_OPENCV_INCLUDE_DIR}")
  list(APPEND OpenCV_LIBS opencv_${module})
endforeach()
