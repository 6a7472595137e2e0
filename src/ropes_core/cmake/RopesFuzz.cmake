# RopesFuzz.cmake: ropes_add_fuzz_harness(), the one way a ropes package adds a libFuzzer
# harness (its warning flags are the package's: ropes_package()). Installed with ropes_core
# (find_package(ropes_core) includes it), so every package of the workspace, and a user's,
# declares harnesses the same way.
#
#   ropes_add_fuzz_harness(NAME <name> SOURCE <file.cpp> [LIBRARIES <targets>...]
#                          [DEFINITIONS <defs>...] [INCLUDES <dirs>...])
#
# The source defines `extern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t)`. Its
# inputs live beside it: fuzz/corpus/<name>/ (a short corpus of valid inputs) and
# fuzz/regressions/<name>/ (every input that once crashed or leaked, kept). From it come:
#   - with BUILD_TESTING, <name>_replay: the harness with a main() that feeds it every file of
#     both folders once, and the ctest test fuzz.<name> (label unit) running it; every build
#     has it, gcc's Release build and ci/test --sanitize included
#   - with ROPES_FUZZ=ON (clang only), <name>_fuzz: the harness linked with libFuzzer, listed
#     in <build>/fuzz_harnesses.txt ("name executable corpus regressions" a line) for ci/fuzz
include_guard(GLOBAL)
option(ROPES_FUZZ "Build the libFuzzer harnesses (clang; see ci/fuzz)" OFF)
if(ROPES_FUZZ AND NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "ROPES_FUZZ=ON needs clang (libFuzzer), not ${CMAKE_CXX_COMPILER_ID}: "
    "configure with CXX=clang++, as ci/fuzz does")
endif()
set(_ropes_fuzz_dir "${CMAKE_CURRENT_LIST_DIR}")
set_property(GLOBAL PROPERTY ROPES_FUZZ_HARNESSES "")

function(ropes_add_fuzz_harness)
  cmake_parse_arguments(_f "" "NAME;SOURCE" "LIBRARIES;DEFINITIONS;INCLUDES" ${ARGN})
  if(NOT _f_NAME OR NOT _f_SOURCE)
    message(FATAL_ERROR "ropes_add_fuzz_harness: NAME and SOURCE are required")
  endif()
  set(_corpus "${CMAKE_CURRENT_SOURCE_DIR}/fuzz/corpus/${_f_NAME}")
  set(_regressions "${CMAKE_CURRENT_SOURCE_DIR}/fuzz/regressions/${_f_NAME}")
  if(NOT IS_DIRECTORY "${_corpus}")
    message(FATAL_ERROR "ropes_add_fuzz_harness(${_f_NAME}): no corpus folder ${_corpus}")
  endif()
  # the harness source compiles once, into an object library both executables link: the
  # sanitizer build has both, and compiled each of its 10 harness sources twice
  set(_objects ${_f_NAME}_harness_objects)
  if(BUILD_TESTING OR ROPES_FUZZ)
    add_library(${_objects} OBJECT ${_f_SOURCE})
    target_link_libraries(${_objects} PRIVATE ${_f_LIBRARIES})
    target_compile_definitions(${_objects} PRIVATE ${_f_DEFINITIONS})
    target_include_directories(${_objects} PRIVATE ${_f_INCLUDES})
  endif()
  set(_targets)
  if(BUILD_TESTING)
    add_executable(${_f_NAME}_replay "${_ropes_fuzz_dir}/fuzz_replay_main.cpp")
    list(APPEND _targets ${_f_NAME}_replay)
    add_test(NAME fuzz.${_f_NAME} COMMAND ${_f_NAME}_replay "${_corpus}" "${_regressions}")
    set_tests_properties(fuzz.${_f_NAME} PROPERTIES LABELS unit TIMEOUT 300)
  endif()
  if(ROPES_FUZZ)
    add_executable(${_f_NAME}_fuzz)
    target_link_options(${_f_NAME}_fuzz PRIVATE -fsanitize=fuzzer)
    list(APPEND _targets ${_f_NAME}_fuzz)
    set_property(GLOBAL APPEND_STRING PROPERTY ROPES_FUZZ_HARNESSES
      "${_f_NAME} ${CMAKE_CURRENT_BINARY_DIR}/${_f_NAME}_fuzz ${_corpus} ${_regressions}\n")
  endif()
  foreach(_t IN LISTS _targets)
    target_link_libraries(${_t} PRIVATE ${_objects} ${_f_LIBRARIES})
  endforeach()
endfunction()

# call once at the end of the CMakeLists: the list ci/fuzz reads, rewritten at each configure
function(ropes_write_fuzz_list)
  get_property(_list GLOBAL PROPERTY ROPES_FUZZ_HARNESSES)
  if(_list)
    file(WRITE "${CMAKE_BINARY_DIR}/fuzz_harnesses.txt" "${_list}")
  else()
    file(REMOVE "${CMAKE_BINARY_DIR}/fuzz_harnesses.txt")
  endif()
endfunction()
