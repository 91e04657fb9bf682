# sparseloop_build_consumer(PREFIX BUILD): configures, builds and runs examples/consumer against
# an installed sparseloop under PREFIX through find_package(sparseloop). Included by
# consumer_test.cmake (cmake --install) and package_test.cmake (the .deb).
function(sparseloop_build_consumer prefix build)
  file(REMOVE_RECURSE ${build})
  execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/consumer -B ${build}
    -G ${CMAKE_GENERATOR} -DCMAKE_PREFIX_PATH=${prefix} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer configure against ${prefix} failed: ${rc}")
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} --build ${build} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer build against ${prefix} failed: ${rc}")
  endif()
  execute_process(COMMAND ${build}/consumer RESULT_VARIABLE rc OUTPUT_VARIABLE out)
  message(STATUS "consumer printed: ${out}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer run failed: ${rc}")
  endif()
endfunction()
