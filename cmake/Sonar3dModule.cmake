# One library target per module of src/ (docs/design.md, "Layers"):
#   sonar3d_add_module(<module>)   in src/<module>/CMakeLists.txt
# builds sonar3d_<module> (alias sonar3d::<module>, exported as sonar3d::<module>) from
# src/<module>/*.cpp, with the public include directory, C++17 and the project's warnings. The
# module's CMakeLists.txt then links the modules below it — PUBLIC when its public headers include
# them, PRIVATE otherwise — and its own dependencies. tests/check_layers.py (the test
# `layering`) fails when a file includes a module its target does not link.
function(sonar3d_add_module module)
  set(target sonar3d_${module})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
  add_library(${target} ${sources})
  add_library(sonar3d::${module} ALIAS ${target})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
    $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_compile_features(${target} PUBLIC cxx_std_17)
  sonar3d_set_target_properties(${target})
  set_target_properties(${target} PROPERTIES
    EXPORT_NAME ${module}
    POSITION_INDEPENDENT_CODE ON
    VERSION ${PROJECT_VERSION}
    SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR})
  install(TARGETS ${target} EXPORT sonar3dTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
    RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endfunction()
