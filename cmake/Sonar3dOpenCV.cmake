# Debian splits OpenCV into per-module -dev packages; only the full libopencv-dev ships the CMake
# config, so the three modules sonar3d uses are imported here as opencv::core, opencv::imgproc and
# opencv::imgcodecs. Used by the build (Sonar3dDependencies.cmake) and, for a static libsonar3d,
# by the installed sonar3dConfig.cmake.
find_path(OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
foreach(_sonar3d_cv core imgproc imgcodecs)
  find_library(OPENCV_${_sonar3d_cv}_LIBRARY opencv_${_sonar3d_cv})
  if(NOT OPENCV_INCLUDE_DIR OR NOT OPENCV_${_sonar3d_cv}_LIBRARY)
    message(FATAL_ERROR "OpenCV ${_sonar3d_cv} not found (Debian: libopencv-${_sonar3d_cv}-dev)")
  endif()
  if(NOT TARGET opencv::${_sonar3d_cv})
    add_library(opencv::${_sonar3d_cv} UNKNOWN IMPORTED)
    set_target_properties(opencv::${_sonar3d_cv} PROPERTIES
      IMPORTED_LOCATION ${OPENCV_${_sonar3d_cv}_LIBRARY}
      INTERFACE_INCLUDE_DIRECTORIES ${OPENCV_INCLUDE_DIR})
  endif()
endforeach()
