# The test `install_and_use` (cmake -P): an install that stands alone.
#   1. cmake --install BUILD_DIR into WORK_DIR/prefix, then move the prefix to WORK_DIR/moved, so
#      nothing can work through a path the build knows;
#   2. build examples/carve_sphere against it with find_package(sonar3d CONFIG) and run it;
#   3. run the installed sonar3d: --version, and `report` on a small plan directory, checking that
#      the page was made from the installed web assets (not the source tree's web/);
#   4. import the installed Python package (when built) and check its __version__.
# Inputs: BUILD_DIR SOURCE_DIR WORK_DIR VERSION CXX_COMPILER [CXX_LAUNCHER] [PYTHON PYTHON_DIR].
cmake_minimum_required(VERSION 3.20)

function(run)
  cmake_parse_arguments(R "" "OUTPUT;WORKING_DIRECTORY" "COMMAND" ${ARGN})
  if(NOT R_WORKING_DIRECTORY)
    set(R_WORKING_DIRECTORY ${WORK_DIR})
  endif()
  execute_process(COMMAND ${R_COMMAND} WORKING_DIRECTORY ${R_WORKING_DIRECTORY}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " cmd "${R_COMMAND}")
    message(FATAL_ERROR "failed (${rc}): ${cmd}\n${out}\n${err}")
  endif()
  if(R_OUTPUT)
    set(${R_OUTPUT} "${out}" PARENT_SCOPE)
  endif()
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

# 1. Install, then move the prefix.
run(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix)
file(RENAME ${WORK_DIR}/prefix ${WORK_DIR}/moved)
set(P ${WORK_DIR}/moved)
foreach(f bin/sonar3d include/sonar3d/version.hpp include/sonar3d/recon/carve.hpp
          lib/cmake/sonar3d/sonar3dConfig.cmake lib/cmake/sonar3d/sonar3dConfigVersion.cmake
          share/sonar3d/web/report_template.html share/sonar3d/web/dist/three-bundle.js
          share/doc/sonar3d/LICENSE)
  if(NOT EXISTS ${P}/${f})
    message(FATAL_ERROR "the install lacks ${f}")
  endif()
endforeach()
file(GLOB targets ${P}/lib/cmake/sonar3d/sonar3dTargets.cmake)
file(READ ${targets} text)
if(NOT text MATCHES "cxx_std_17")
  message(FATAL_ERROR "sonar3d::sonar3d does not carry cxx_std_17 as a usage requirement")
endif()

# 2. The example, as a user's project: only the moved prefix is searched.
set(launcher "")
if(CXX_LAUNCHER)
  set(launcher -DCMAKE_CXX_COMPILER_LAUNCHER=${CXX_LAUNCHER})
endif()
run(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/carve_sphere -B ${WORK_DIR}/example
            -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX_COMPILER} ${launcher}
            -DCMAKE_PREFIX_PATH=${P} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
file(STRINGS ${WORK_DIR}/example/CMakeCache.txt dir_line REGEX "^sonar3d_DIR:")
if(NOT dir_line STREQUAL "sonar3d_DIR:PATH=${P}/lib/cmake/sonar3d")
  message(FATAL_ERROR "the example found sonar3d elsewhere: ${dir_line}")
endif()
run(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/example)
run(COMMAND ${WORK_DIR}/example/carve_sphere OUTPUT out)
message(STATUS "carve_sphere: ${out}")
if(NOT out MATCHES "^sonar3d ${VERSION}: carved [0-9]+ points from 71 frames; median distance to the sphere 0\\.0[0-2][0-9]* m")
  message(FATAL_ERROR "unexpected output of carve_sphere: ${out}")
endif()

# 3. The installed executable, run from outside the source and build trees.
run(COMMAND ${P}/bin/sonar3d --version OUTPUT out)
if(NOT out STREQUAL "sonar3d ${VERSION}\n")
  message(FATAL_ERROR "sonar3d --version printed '${out}'")
endif()
set(plan ${WORK_DIR}/plan)
file(WRITE ${plan}/points/p0/cloud.ply "ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
end_header
0 0 0
1 0 0
0 1 0
0 0 1
")
file(WRITE ${plan}/results.json [=[{
  "version": 1, "rank_by": "median_to_coverage", "rank_order": "ascending", "constraints": [],
  "axes": {"spacing_m": [0.02]},
  "points": [{"id": "p0", "params": {"spacing_m": 0.02}, "objects": [], "status": "ok",
              "message": "", "runtime_s": 1.0, "peak_rss_mb": 100, "data_bytes": 1000, "rank": 1,
              "metrics": {"median_error_m": 0.01, "mean_error_m": 0.01, "coverage": 0.9,
                          "outliers": 0.0, "median_to_coverage": 0.011, "num_points": 4},
              "cloud": "points/p0/cloud.ply"}]
}]=])
# A marker in the installed stylesheet shows the page was made from the installed assets.
file(APPEND ${P}/share/sonar3d/web/report.css "\n/* installed-assets-marker */\n")
run(COMMAND ${CMAKE_COMMAND} -E env --unset=SONAR3D_WEB_DIR
            ${P}/bin/sonar3d report ${plan} -o ${WORK_DIR}/report.html -q)
file(READ ${WORK_DIR}/report.html html)
if(NOT html MATCHES "installed-assets-marker")
  message(FATAL_ERROR "sonar3d report did not use the installed web assets in ${P}/share")
endif()

# 4. The Python package of the install.
if(PYTHON)
  set(site ${P}/${PYTHON_DIR})
  run(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${site} PYTHONDONTWRITEBYTECODE=1
              ${PYTHON} -c "import sonar3d\nprint(sonar3d.__version__, sonar3d.__file__)"
      OUTPUT out)
  if(NOT out MATCHES "^${VERSION} ${P}/")
    message(FATAL_ERROR "the installed Python package says: ${out}")
  endif()
endif()

file(REMOVE_RECURSE ${WORK_DIR})
message(STATUS "install_and_use: PASS")
