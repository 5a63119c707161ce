# What `cmake --install build --prefix P` adds besides the targets (docs/install.md):
#   P/lib/cmake/sonar3d/     sonar3dConfig.cmake, sonar3dConfigVersion.cmake, sonar3dTargets*.cmake
#   P/share/sonar3d/web/     the report's web assets (found relative to P/bin/sonar3d)
#   P/share/doc/sonar3d/     LICENSE and the licences of what the install bundles
# and the test `install_and_use`, which installs into a temporary prefix and uses the result.
include(CMakePackageConfigHelpers)

set(SONAR3D_CONFIG_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/sonar3d)
get_target_property(_sonar3d_type sonar3d_core TYPE)  # every module is built alike
if(_sonar3d_type STREQUAL "STATIC_LIBRARY")
  set(SONAR3D_STATIC ON)
else()
  set(SONAR3D_STATIC OFF)
endif()
if(MPI_CXX_FOUND)
  set(SONAR3D_WITH_MPI ON)
else()
  set(SONAR3D_WITH_MPI OFF)
endif()

install(EXPORT sonar3dTargets NAMESPACE sonar3d:: DESTINATION ${SONAR3D_CONFIG_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/sonar3dConfig.cmake.in
  ${PROJECT_BINARY_DIR}/sonar3dConfig.cmake INSTALL_DESTINATION ${SONAR3D_CONFIG_DIR})
# 0.x: a minor release may change the API, so only the same major.minor is compatible.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/sonar3dConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/sonar3dConfig.cmake
              ${PROJECT_BINARY_DIR}/sonar3dConfigVersion.cmake
              ${PROJECT_SOURCE_DIR}/cmake/Sonar3dOpenCV.cmake
        DESTINATION ${SONAR3D_CONFIG_DIR})

# The report's web assets: the project's own files (sweep and scene pages) and the two npm-built
# libraries (`npm ci` in web/, scripts/install-deps.sh), in the layout report.cpp reads. OPTIONAL: a build
# without them installs, and `sonar3d report` then says which asset is missing.
set(_web ${PROJECT_SOURCE_DIR}/web)
set(_web_dest ${CMAKE_INSTALL_DATADIR}/sonar3d/web)
install(FILES ${_web}/report_template.html ${_web}/report.css ${_web}/report.js
              ${_web}/common.js ${_web}/scene.js
        DESTINATION ${_web_dest})
install(FILES ${_web}/dist/three-bundle.js DESTINATION ${_web_dest}/dist OPTIONAL)
install(FILES ${_web}/node_modules/three/LICENSE DESTINATION ${_web_dest}/dist
        RENAME LICENSE-three.js OPTIONAL)
install(FILES ${_web}/node_modules/plotly.js-basic-dist-min/plotly-basic.min.js
              ${_web}/node_modules/plotly.js-basic-dist-min/LICENSE
        DESTINATION ${_web_dest}/node_modules/plotly.js-basic-dist-min OPTIONAL)
if(NOT EXISTS ${_web}/dist/three-bundle.js OR NOT EXISTS
   ${_web}/node_modules/plotly.js-basic-dist-min/plotly-basic.min.js)
  message(STATUS "web/node_modules or web/dist missing (run scripts/install-deps.sh): "
                 "an install made now has no report assets")
endif()

install(FILES ${PROJECT_SOURCE_DIR}/LICENSE ${PROJECT_SOURCE_DIR}/README.md
        DESTINATION ${CMAKE_INSTALL_DOCDIR})

if(SONAR3D_BUILD_TESTS)
  # Installs this build into a temporary prefix, moves the prefix (the build's paths are then
  # useless), builds examples/ against it with find_package(sonar3d CONFIG) and runs the installed
  # sonar3d: --version, and `report` with the installed web assets.
  set(_sonar3d_test_python "")
  if(SONAR3D_BUILD_PYTHON)
    set(_sonar3d_test_python ${Python3_EXECUTABLE})
  endif()
  add_test(NAME install_and_use
           COMMAND ${CMAKE_COMMAND}
                   -DBUILD_DIR=${PROJECT_BINARY_DIR}
                   -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
                   -DWORK_DIR=${PROJECT_BINARY_DIR}/install_and_use
                   -DVERSION=${PROJECT_VERSION}
                   -DCXX_COMPILER=${CMAKE_CXX_COMPILER}
                   -DCXX_LAUNCHER=${CMAKE_CXX_COMPILER_LAUNCHER}
                   -DPYTHON=${_sonar3d_test_python}
                   -DPYTHON_DIR=${SONAR3D_PYTHON_INSTALL_DIR}
                   -P ${PROJECT_SOURCE_DIR}/cmake/TestInstall.cmake)
  set_tests_properties(install_and_use PROPERTIES TIMEOUT 600)
endif()
