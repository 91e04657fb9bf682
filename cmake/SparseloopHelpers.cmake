# sparseloop_add_module(NAME <m> SOURCES <...> [PUBLIC_DEPS <...>] [PRIVATE_DEPS <...>])
# Creates the static library sparseloop_<m> (alias sparseloop::<m>), exported and installed,
# and records it in the global property SPARSELOOP_MODULE_TARGETS_PROP for the umbrella target.
function(sparseloop_add_module)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  set(target sparseloop_${ARG_NAME})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(sparseloop::${ARG_NAME} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_NAME})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>
    PRIVATE ${PROJECT_SOURCE_DIR}/src)
  target_compile_features(${target} PUBLIC cxx_std_20)
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  install(TARGETS ${target} EXPORT sparseloopTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  set_property(GLOBAL APPEND PROPERTY SPARSELOOP_MODULE_TARGETS_PROP ${target})
endfunction()

# sparseloop_add_test(NAME <t> SOURCES <...> LIBS <...> [LABELS <...>])
# A GoogleTest binary (includes: tests/, tests/support/ (fixtures shared with bench/), src/);
# each TEST becomes a ctest test (discovered before the test runs, so the
# build never executes test code). The test sees SPARSELOOP_DATA_DIR and SPARSELOOP_SOURCE_DIR.
# Labels (docs/TESTING.md): a level, `unit` (the default: one module, synthetic or small real
# inputs) or `scenario` (end to end on renders or real data), plus an area (cli, runtime, ros, ...).
# `sanitize` marks the scenarios the sanitizer stages run besides every unit test. The custom
# target sanitize_tests builds exactly the binaries those stages run.
if(NOT TARGET sanitize_tests)
  add_custom_target(sanitize_tests)
endif()
function(sparseloop_add_test)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LIBS} sparseloop_test_main)
  target_include_directories(${ARG_NAME} PRIVATE ${PROJECT_SOURCE_DIR}/tests
    ${PROJECT_SOURCE_DIR}/tests/support ${PROJECT_SOURCE_DIR}/src)
  if(NOT "unit" IN_LIST ARG_LABELS AND NOT "scenario" IN_LIST ARG_LABELS)
    list(PREPEND ARG_LABELS unit)
  endif()
  if("unit" IN_LIST ARG_LABELS OR "sanitize" IN_LIST ARG_LABELS)
    add_dependencies(sanitize_tests ${ARG_NAME})
  endif()
  gtest_discover_tests(${ARG_NAME} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 60
    TEST_LIST ${ARG_NAME}_TESTS
    PROPERTIES ENVIRONMENT "SPARSELOOP_TEST_TMP=${CMAKE_BINARY_DIR}/test_tmp")
  # Labels are set after discovery by a file ctest includes next: gtest_discover_tests passes its
  # PROPERTIES on as flat arguments, so a list of labels would keep only its first element. A
  # binary that was not built keeps its labels too, so a labelled stage cannot pass by running
  # nothing.
  set(labels_file "${CMAKE_CURRENT_BINARY_DIR}/${ARG_NAME}_labels.cmake")
  file(WRITE "${labels_file}"
    "if(DEFINED ${ARG_NAME}_TESTS)\n"
    "  set_tests_properties(\${${ARG_NAME}_TESTS} PROPERTIES LABELS \"${ARG_LABELS}\")\n"
    "else()\n"
    "  set_tests_properties(${ARG_NAME}_NOT_BUILT PROPERTIES LABELS \"${ARG_LABELS}\")\n"
    "endif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${labels_file}")
endfunction()
