# Installs the build tree into a temporary prefix, then configures, builds and runs
# examples/consumer against it with find_package(sparseloop).
include(${CMAKE_CURRENT_LIST_DIR}/consumer_build.cmake)
set(prefix ${BINARY_DIR}/consumer_test/prefix)
file(REMOVE_RECURSE ${prefix})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BINARY_DIR} --prefix ${prefix}
  RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "install failed: ${rc}")
endif()
if(NOT EXISTS ${prefix}/share/doc/sparseloop/LICENSE)
  message(FATAL_ERROR "install did not put LICENSE in ${prefix}/share/doc/sparseloop")
endif()
sparseloop_build_consumer(${prefix} ${BINARY_DIR}/consumer_test/build)
