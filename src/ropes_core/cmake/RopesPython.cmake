# RopesPython.cmake: the Python bindings of a package (pybind11, numpy), installed with ropes_core
# beside RopesPackage.cmake (find_package(ropes_core) includes both).
#
#   ropes_add_python_module(<name> SOURCES <cpp>... LIBRARIES <targets>...
#                           [PYTHON_FILES <py>...])
#   ropes_add_pytest(<test name> DIRECTORY <dir> [TIMEOUT <s>] [LABELS <labels>...]
#                    [ENVIRONMENT <VAR=value>...])
#
# ROPES_PYTHON (cache: AUTO, the default, ON or OFF) decides whether they do anything: AUTO
# builds the bindings when pybind11 and numpy are found for the interpreter, ON requires them
# (a fatal error naming what is missing), OFF leaves them out (the sanitizer build does: a
# Python interpreter cannot load ASan-instrumented modules without preloading the runtime).
# ROPES_PYTHON_ENABLED tells the caller which it is.
#
# The interpreter is Debian's /usr/bin/python3 (the one python3-numpy, python3-pytest and
# pybind11-dev are built for; a pyenv python3 first on PATH lacks them), else the first
# python3 FindPython3 finds. Python3_EXECUTABLE picks another, but colcon's setup.bash puts
# colcon's own Python version's site-packages on PYTHONPATH: the two must be the same version.
#
# ropes_add_python_module() builds the extension module ropes.<name> from SOURCES (linking
# LIBRARIES and ropes_core/python.hpp's helpers) and installs it, with the PYTHON_FILES (the
# package's pure-Python modules, each into ropes/), into lib/pythonX.Y/site-packages/ropes of
# the package's install prefix: where colcon's setup.bash puts PYTHONPATH.
#
# ropes_add_pytest() runs pytest on DIRECTORY as one ctest test (label python, plus LABELS;
# not registered when the interpreter has no pytest),
# with the install prefix's site-packages first on PYTHONPATH and the ENVIRONMENT variables
# set (generator expressions allowed: the path of a tool to compare with), and writes pytest's JUnit XML
# into the build directory, so that colcon test-result counts each Python test.
include_guard(GLOBAL)

macro(ropes_python_setup)
  set(ROPES_PYTHON AUTO CACHE STRING "Build the Python bindings: AUTO, ON or OFF")
  string(TOUPPER "${ROPES_PYTHON}" _ropes_python)
  if(NOT _ropes_python MATCHES "^(AUTO|ON|OFF)$")
    message(FATAL_ERROR "ROPES_PYTHON is '${ROPES_PYTHON}'; expected AUTO, ON or OFF")
  endif()
  set(ROPES_PYTHON_ENABLED FALSE)
  set(_ropes_python_missing "")
  if(NOT _ropes_python STREQUAL "OFF")
    if(NOT Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
      set(Python3_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "The Python of the bindings")
    endif()
    find_package(Python3 3.9 QUIET COMPONENTS Interpreter Development.Module)
    if(NOT Python3_FOUND)
      set(_ropes_python_missing "a Python 3.9+ interpreter with its headers (python3-dev)")
    else()
      execute_process(COMMAND "${Python3_EXECUTABLE}" -c "import numpy; print(numpy.__version__)"
        RESULT_VARIABLE _ropes_numpy_rc OUTPUT_QUIET ERROR_QUIET)
      find_package(pybind11 2.6 CONFIG QUIET)
      if(NOT _ropes_numpy_rc EQUAL 0)
        set(_ropes_python_missing "numpy for ${Python3_EXECUTABLE} (python3-numpy)")
      elseif(NOT pybind11_FOUND)
        set(_ropes_python_missing "pybind11 (pybind11-dev)")
      else()
        set(ROPES_PYTHON_ENABLED TRUE)
        set(ROPES_PYTHON_SITE
          "${CMAKE_INSTALL_LIBDIR}/python${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}/site-packages")
      endif()
    endif()
    if(_ropes_python STREQUAL "ON" AND NOT ROPES_PYTHON_ENABLED)
      message(FATAL_ERROR "ROPES_PYTHON=ON but ${_ropes_python_missing} was not found")
    endif()
  endif()
  if(ROPES_PYTHON_ENABLED)
    message(STATUS "${PROJECT_NAME}: Python bindings TRUE (${Python3_EXECUTABLE})")
  elseif(_ropes_python_missing)
    message(STATUS "${PROJECT_NAME}: Python bindings FALSE (no ${_ropes_python_missing})")
  else()
    message(STATUS "${PROJECT_NAME}: Python bindings FALSE (ROPES_PYTHON=OFF)")
  endif()
endmacro()

function(ropes_add_python_module name)
  cmake_parse_arguments(_m "" "" "SOURCES;LIBRARIES;PYTHON_FILES" ${ARGN})
  if(_m_UNPARSED_ARGUMENTS OR NOT _m_SOURCES)
    message(FATAL_ERROR "ropes_add_python_module(${name}): expected SOURCES, LIBRARIES and "
      "PYTHON_FILES; got ${ARGN}")
  endif()
  if(NOT ROPES_PYTHON_ENABLED)
    return()
  endif()
  # NO_EXTRAS: no link-time optimisation (it doubles the link time for nothing measurable)
  pybind11_add_module(${name} MODULE NO_EXTRAS ${_m_SOURCES})
  target_link_libraries(${name} PRIVATE ${_m_LIBRARIES})
  # the numpy headers are not needed: pybind11/numpy.h reaches numpy through Python
  install(TARGETS ${name} LIBRARY DESTINATION ${ROPES_PYTHON_SITE}/ropes)
  if(_m_PYTHON_FILES)
    install(FILES ${_m_PYTHON_FILES} DESTINATION ${ROPES_PYTHON_SITE}/ropes)
  endif()
endfunction()

function(ropes_add_pytest test_name)
  cmake_parse_arguments(_t "" "DIRECTORY;TIMEOUT" "LABELS;ENVIRONMENT" ${ARGN})
  if(NOT ROPES_PYTHON_ENABLED OR NOT BUILD_TESTING)
    return()
  endif()
  if(NOT DEFINED ROPES_PYTEST_FOUND)
    execute_process(COMMAND "${Python3_EXECUTABLE}" -c "import pytest"
      RESULT_VARIABLE _ropes_pytest_rc OUTPUT_QUIET ERROR_QUIET)
    if(_ropes_pytest_rc EQUAL 0)
      set(ROPES_PYTEST_FOUND TRUE CACHE INTERNAL "pytest for the Python bindings' tests")
    else()
      set(ROPES_PYTEST_FOUND FALSE CACHE INTERNAL "pytest for the Python bindings' tests")
    endif()
  endif()
  if(NOT ROPES_PYTEST_FOUND)
    message(STATUS "${PROJECT_NAME}: no pytest for ${Python3_EXECUTABLE} (python3-pytest): "
      "${test_name} is not registered")
    return()
  endif()
  if(NOT _t_TIMEOUT)
    set(_t_TIMEOUT 300)
  endif()
  set(_xml "${PROJECT_BINARY_DIR}/test_results/${PROJECT_NAME}/${test_name}.xml")
  add_test(NAME ${test_name}
    COMMAND "${Python3_EXECUTABLE}" -m pytest -q -p no:cacheprovider "--junitxml=${_xml}"
            -o junit_suite_name=${test_name} "${_t_DIRECTORY}"
    WORKING_DIRECTORY "${PROJECT_BINARY_DIR}")
  set_tests_properties(${test_name} PROPERTIES LABELS "python;${_t_LABELS}" TIMEOUT ${_t_TIMEOUT}
    ENVIRONMENT "${_t_ENVIRONMENT}"
    ENVIRONMENT_MODIFICATION
      "PYTHONPATH=path_list_prepend:${CMAKE_INSTALL_PREFIX}/${ROPES_PYTHON_SITE}")
endfunction()
