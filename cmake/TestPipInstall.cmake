# The test `python_pip_install` (cmake -P): the README's `pip install` as a user runs it, with
# Debian's pip into the user site of a temporary HOME, then `import sonar3d` with no PYTHONPATH.
# SONAR3D_CMAKE_BUILD_DIR makes setup.py reuse this build's compiled module instead of compiling
# the library again (a fresh `pip install .` configures its own build under build/pip/).
# Inputs: PYTHON SOURCE_DIR BUILD_DIR WORK_DIR VERSION.
cmake_minimum_required(VERSION 3.20)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR}/home)
set(env ${CMAKE_COMMAND} -E env --unset=PYTHONPATH --unset=PYTHONUSERBASE --unset=PIP_USER
        HOME=${WORK_DIR}/home PIP_DISABLE_PIP_VERSION_CHECK=1 PYTHONDONTWRITEBYTECODE=1)

execute_process(COMMAND ${env} SONAR3D_CMAKE_BUILD_DIR=${BUILD_DIR}
                        ${PYTHON} -m pip install --user --break-system-packages
                        --no-build-isolation --no-index ${SOURCE_DIR}
                WORKING_DIRECTORY ${SOURCE_DIR}
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "pip install failed (${rc}; Debian packages python3-pip python3-setuptools "
                      "python3-wheel):\n${out}\n${err}")
endif()

# From a directory holding no sonar3d sources, with the user site of the temporary HOME only.
execute_process(COMMAND ${env} ${PYTHON} -c
                        "import sonar3d\nprint(sonar3d.__version__, sonar3d.__file__)\nprint(sonar3d.CarveConfig())"
                WORKING_DIRECTORY ${WORK_DIR}
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT out MATCHES "^${VERSION} ${WORK_DIR}/home/\\.local/lib/python3[.0-9]*/site-packages/sonar3d/__init__\\.py\nCarveConfig\\(voxel_size=")
  message(FATAL_ERROR "import sonar3d after pip install: rc ${rc}\n${out}\n${err}")
endif()

execute_process(COMMAND ${env} ${PYTHON} -m pip uninstall --yes --break-system-packages sonar3d
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "pip uninstall failed:\n${out}\n${err}")
endif()
file(REMOVE_RECURSE ${WORK_DIR})
message(STATUS "python_pip_install: PASS")
