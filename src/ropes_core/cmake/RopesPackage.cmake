# RopesPackage.cmake: what every package of the workspace declares the same way. Installed with
# ropes_core (find_package(ropes_core) includes it); ropes_core includes it from its source.
#
#   project(<name> LANGUAGES CXX)
#   find_package(ropes_core 0.1 CONFIG REQUIRED)   # ropes_core itself: include(cmake/...)
#   ropes_package()
#   ropes_add_library(<target> [EXPORT_NAME <name>] <sources>...)
#   ... other targets ...
#   ropes_install_package(TARGETS <libraries>... [EXECUTABLES <tools>...]
#                         [CONFIG_FILES <files>...] [NO_INCLUDE_DIR])
#
# ropes_package() reads the version from package.xml (the one source of truth; the file's
# <name> must be the project's), falls back to a Release build (colcon sets no build type),
# asks for C++17 without extensions (an explicit -std=c++17 in compile_commands.json, so
# clang-tidy parses as the compiler does), includes GNUInstallDirs, CMakePackageConfigHelpers
# and CTest, and gives every target of the package the workspace's warning flags:
# -Wall -Wextra -Wpedantic -Wshadow, and -Werror with ROPES_WERROR=ON (CI).
#
# ropes_add_library() adds a library the way every package declares one: the alias
# <name>::<export name> (EXPORT_NAME, default the target's name), C++17 for its users, the
# package's include/ (when it has one) on their include path, and position-independent
# code, so that a user's shared library can link the static library.
#
# ropes_find_streaming(<var> <what>) is the option ROPES_WITH_DDS of a package whose streaming
# executables need ropes_msgs built with Fast DDS: AUTO (the default) builds them when
# ropes_msgs has the types, ON requires it (a fatal error with ropes_msgs' reason), OFF leaves
# them out. Sets <var> TRUE when ropes_msgs::ropes_msgs can be linked, and prints
# "<package>: <what> TRUE|FALSE".
#
# ropes_add_gtests(<target>) registers a GoogleTest executable's tests with ctest, each at run
# time (DISCOVERY_MODE PRE_TEST): those whose suite or name holds "Golden" (pinned values) with
# the label golden, the others with the label unit.
#
# ropes_install_package() installs the libraries with an export set <name>Targets in the
# namespace <name>::, include/<name>/, the config file made from cmake/<name>Config.cmake.in
# with a SameMajorVersion version file, package.xml into share/<name>/, and the executables
# into bin/. CONFIG_FILES go beside the config file (CMake modules the config includes);
# NO_INCLUDE_DIR leaves include/<name>/ to the caller.
include_guard(GLOBAL)
include(CMakePackageConfigHelpers)

macro(ropes_package)
  file(READ "${PROJECT_SOURCE_DIR}/package.xml" _ropes_package_xml)
  if(NOT _ropes_package_xml MATCHES "<name>([^<]*)</name>")
    message(FATAL_ERROR "${PROJECT_SOURCE_DIR}/package.xml: no <name> element")
  endif()
  if(NOT CMAKE_MATCH_1 STREQUAL PROJECT_NAME)
    message(FATAL_ERROR "${PROJECT_SOURCE_DIR}/package.xml names the package '${CMAKE_MATCH_1}'; "
      "expected the project's name, '${PROJECT_NAME}'")
  endif()
  if(NOT _ropes_package_xml MATCHES "<version>([0-9]+)\\.([0-9]+)\\.([0-9]+)</version>")
    message(FATAL_ERROR "${PROJECT_SOURCE_DIR}/package.xml: no <version>X.Y.Z</version> element")
  endif()
  set(PROJECT_VERSION "${CMAKE_MATCH_1}.${CMAKE_MATCH_2}.${CMAKE_MATCH_3}")
  set(PROJECT_VERSION_MAJOR ${CMAKE_MATCH_1})
  set(PROJECT_VERSION_MINOR ${CMAKE_MATCH_2})
  set(PROJECT_VERSION_PATCH ${CMAKE_MATCH_3})
  set(${PROJECT_NAME}_VERSION ${PROJECT_VERSION})
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS
    "${PROJECT_SOURCE_DIR}/package.xml")

  if(NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
    set(CMAKE_BUILD_TYPE Release CACHE STRING "Build type" FORCE)
  endif()
  option(ROPES_WERROR "Treat compiler warnings as errors (CI turns this on)" OFF)
  set(CMAKE_CXX_STANDARD 17)
  set(CMAKE_CXX_STANDARD_REQUIRED ON)
  set(CMAKE_CXX_EXTENSIONS OFF)
  include(GNUInstallDirs)
  include(CTest)
  add_compile_options(-Wall -Wextra -Wpedantic -Wshadow $<$<BOOL:${ROPES_WERROR}>:-Werror>)
endmacro()

function(ropes_add_library target)
  cmake_parse_arguments(_l "" "EXPORT_NAME" "" ${ARGN})
  set(_name ${target})
  if(_l_EXPORT_NAME)
    set(_name ${_l_EXPORT_NAME})
  endif()
  add_library(${target} ${_l_UNPARSED_ARGUMENTS})
  add_library(${PROJECT_NAME}::${_name} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${_name} POSITION_INDEPENDENT_CODE ON)
  target_compile_features(${target} PUBLIC cxx_std_17)
  if(IS_DIRECTORY "${PROJECT_SOURCE_DIR}/include")  # CMake refuses a missing include path
    target_include_directories(${target} PUBLIC
      $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  endif()
endfunction()

macro(ropes_find_streaming var what)
  set(ROPES_WITH_DDS AUTO CACHE STRING "Build ${what} (Fast DDS): AUTO, ON or OFF")
  string(TOUPPER "${ROPES_WITH_DDS}" _ropes_with_dds)
  if(NOT _ropes_with_dds MATCHES "^(AUTO|ON|OFF)$")
    message(FATAL_ERROR "ROPES_WITH_DDS is '${ROPES_WITH_DDS}'; expected AUTO, ON or OFF")
  endif()
  set(${var} FALSE)
  if(NOT _ropes_with_dds STREQUAL "OFF")
    find_package(ropes_msgs 0.1 CONFIG QUIET)
    if(ropes_msgs_FOUND)
      set(${var} TRUE)
    elseif(_ropes_with_dds STREQUAL "ON")
      message(FATAL_ERROR "ROPES_WITH_DDS=ON but ropes_msgs with Fast DDS was not found: "
        "${ropes_msgs_NOT_FOUND_MESSAGE}")
    endif()
  endif()
  message(STATUS "${PROJECT_NAME}: ${what} ${${var}}")
endmacro()

function(ropes_add_gtests target)
  include(GoogleTest)
  gtest_discover_tests(${target} DISCOVERY_MODE PRE_TEST TEST_FILTER "-*Golden*"
    PROPERTIES LABELS unit)
  gtest_discover_tests(${target} DISCOVERY_MODE PRE_TEST TEST_FILTER "*Golden*"
    PROPERTIES LABELS golden)
endfunction()

function(ropes_install_package)
  cmake_parse_arguments(_p "NO_INCLUDE_DIR" "" "TARGETS;EXECUTABLES;CONFIG_FILES" ${ARGN})
  if(_p_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "ropes_install_package: unknown arguments ${_p_UNPARSED_ARGUMENTS}")
  endif()
  set(_config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/${PROJECT_NAME})
  if(_p_TARGETS)
    install(TARGETS ${_p_TARGETS} EXPORT ${PROJECT_NAME}Targets
      ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
      LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
      RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
    install(EXPORT ${PROJECT_NAME}Targets NAMESPACE ${PROJECT_NAME}::
      DESTINATION ${_config_dir})
  endif()
  if(_p_EXECUTABLES)
    install(TARGETS ${_p_EXECUTABLES} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
  if(NOT _p_NO_INCLUDE_DIR AND IS_DIRECTORY "${PROJECT_SOURCE_DIR}/include/${PROJECT_NAME}")
    install(DIRECTORY "${PROJECT_SOURCE_DIR}/include/${PROJECT_NAME}"
      DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  endif()
  configure_package_config_file("${PROJECT_SOURCE_DIR}/cmake/${PROJECT_NAME}Config.cmake.in"
    "${PROJECT_BINARY_DIR}/${PROJECT_NAME}Config.cmake" INSTALL_DESTINATION ${_config_dir})
  write_basic_package_version_file("${PROJECT_BINARY_DIR}/${PROJECT_NAME}ConfigVersion.cmake"
    VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
  install(FILES
    "${PROJECT_BINARY_DIR}/${PROJECT_NAME}Config.cmake"
    "${PROJECT_BINARY_DIR}/${PROJECT_NAME}ConfigVersion.cmake"
    ${_p_CONFIG_FILES}
    DESTINATION ${_config_dir})
  install(FILES "${PROJECT_SOURCE_DIR}/package.xml" DESTINATION ${CMAKE_INSTALL_DATADIR}/${PROJECT_NAME})
endfunction()
