# Every dependency comes from a Debian package (scripts/install-deps.sh) and is used through an
# imported target.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(TBB REQUIRED)
find_package(embree 3 REQUIRED)
find_package(assimp REQUIRED)
find_package(yaml-cpp REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(fmt REQUIRED)
# Elevation maps as GeoTIFF (libgdal-dev; CMake's FindGDAL gives GDAL::GDAL) and the swath
# adjustment's robust least squares (libceres-dev, a config package).
find_package(GDAL REQUIRED)
find_package(Ceres REQUIRED)
# ROS 2 bags are sqlite3 databases (libsqlite3-dev; CMake's FindSQLite3 gives SQLite::SQLite3).
find_package(SQLite3 REQUIRED)
# ROS 1 bag chunks are bz2 or lz4 compressed (libbz2-dev, liblz4-dev).
find_package(BZip2 REQUIRED)
# NumPy .npz camera files (IDR/NeuS) are zips of deflated entries (zlib1g-dev).
find_package(ZLIB REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(LZ4 REQUIRED IMPORTED_TARGET liblz4)

# OpenVDB (the carving map, .vdb export): Debian ships only a find module, not a config package.
# Its headers need Boost (libboost-iostreams-dev). The module forces BUILD_SHARED_LIBS ON as a side
# effect: keep the caller's value.
list(APPEND CMAKE_MODULE_PATH /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB
  /usr/lib/cmake/OpenVDB)
set(_sonar3d_shared_libs ${BUILD_SHARED_LIBS})
find_package(OpenVDB REQUIRED COMPONENTS openvdb)
set(BUILD_SHARED_LIBS ${_sonar3d_shared_libs})

include(Sonar3dOpenCV)  # opencv::core, opencv::imgproc, opencv::imgcodecs

if(NOT TARGET embree)
  message(FATAL_ERROR "embree imported target not found")
endif()

# MPI (OpenMPI from Debian) spreads planner sweeps over ranks; optional: without it the planner
# runs on one machine.
find_package(MPI COMPONENTS CXX QUIET)
if(NOT MPI_CXX_FOUND)
  message(WARNING "MPI not found: `sonar3d plan` will run on one machine only")
endif()

# Debian's ROS 1 (roscpp, topic_tools' ShapeShifter, the message packages) for the node
# `sonar3d ros` (apps/sonar3d/cmd_ros.cpp); only the CLI links it. SONAR3D_ROS1 (CMakeLists.txt).
set(SONAR3D_HAVE_ROS1 OFF)
if(NOT SONAR3D_ROS1 STREQUAL "OFF")
  set(_sonar3d_ros1_required "")
  if(SONAR3D_ROS1 STREQUAL "ON")
    set(_sonar3d_ros1_required REQUIRED)
  endif()
  pkg_check_modules(ROS1 ${_sonar3d_ros1_required} QUIET IMPORTED_TARGET roscpp topic_tools
                    sensor_msgs nav_msgs geometry_msgs std_msgs std_srvs diagnostic_msgs
                    visualization_msgs)
  if(ROS1_FOUND)
    set(SONAR3D_HAVE_ROS1 ON)
    message(STATUS "ROS 1 (roscpp ${ROS1_roscpp_VERSION}) found: building `sonar3d ros`")
  else()
    message(STATUS "ROS 1 not found (libroscpp-dev, libtopic-tools-dev, lib*-msgs-dev): "
                   "`sonar3d ros` will say the build has no ROS 1 support")
  endif()
endif()
