# rephoto_library(NAME <concept> SOURCES ... [DEPS ...])
#   Builds target rephoto_<concept> (alias rephoto::<concept>) from src/rephoto/<concept>.
#   Public headers are included as "rephoto/<concept>/<file>.h".
function(rephoto_library)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS" ${ARGN})
  set(target rephoto_${ARG_NAME})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(rephoto::${ARG_NAME} ALIAS ${target})
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR}/src)
  target_link_libraries(${target} PUBLIC ${ARG_DEPS})
  set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
endfunction()

# rephoto_test(NAME <concept>/<name> SOURCES ... [DEPS ...])
#   One GoogleTest executable per test file, registered with ctest under NAME
#   (so `ctest -R metrics/` runs one concept). Uses the shared test main in
#   src/rephoto/testing, which seeds every RNG and locates ../shared/data.
function(rephoto_test)
  if(NOT REPHOTO_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS" ${ARGN})
  string(REPLACE "/" "_" target "test_${ARG_NAME}")
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE rephoto_testing ${ARG_DEPS})
  add_test(NAME ${ARG_NAME} COMMAND ${target} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
endfunction()
