# The Debian package: cpack -G DEB in the build tree, then the .deb is unpacked into a scratch root
# and used as a user would: its Depends name the -dev packages a consumer links, the CLI and the
# ROS node run, the Python module imports, examples/consumer builds against its CMake config, and
# (as root, where dpkg can tell) dpkg would install it on this machine.
# Arguments: SOURCE_DIR, BINARY_DIR, CMAKE_GENERATOR, PYTHON, VERSION, HAVE_ROS.
include(${CMAKE_CURRENT_LIST_DIR}/consumer_build.cmake)
set(work ${BINARY_DIR}/package_test)
set(root ${work}/root)
file(REMOVE_RECURSE ${work} ${BINARY_DIR}/package)

# run(CMD...): runs CMD, fails the test with its output unless it exits 0; its stdout in `out`.
# (No ';' inside an argument: CMake would split it.)
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    list(JOIN ARGN " " cmd)
    message(FATAL_ERROR "${cmd} failed (${rc}):\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

execute_process(COMMAND dpkg --print-architecture OUTPUT_VARIABLE arch OUTPUT_STRIP_TRAILING_WHITESPACE)
run(${CMAKE_CPACK_COMMAND} -G DEB --config ${BINARY_DIR}/CPackConfig.cmake)
set(deb ${BINARY_DIR}/package/sparseloop_${VERSION}_${arch}.deb)
if(NOT EXISTS ${deb})
  file(GLOB made ${BINARY_DIR}/package/*.deb)
  message(FATAL_ERROR "expected ${deb}, cpack made: ${made}")
endif()

run(dpkg-deb --field ${deb} Depends)
# The -dev packages a consumer links (our list) and the shared libraries the binaries link
# (dpkg-shlibdeps: OpenCV's runtime package, whatever its soname suffix).
foreach(dep libceres-dev libopencv-dev libeigen3-dev libfaiss-dev python3-numpy libc6
            "libopencv-core[0-9]+")
  if(NOT out MATCHES "(^|, )${dep}( |,|$)")
    message(FATAL_ERROR "Depends of ${deb} lacks ${dep}: ${out}")
  endif()
endforeach()

file(MAKE_DIRECTORY ${root})
run(dpkg-deb -x ${deb} ${root})
set(usr ${root}/usr)
set(expected bin/sparseloop include/sparseloop/runtime/loop_closing.h
  share/doc/sparseloop/README.md share/doc/sparseloop/LICENSE share/sparseloop/report.py
  share/sparseloop/presets/sparse.json share/sparseloop/presets/dense.json
  lib/python3/dist-packages/sparseloop/__init__.py)
file(GLOB_RECURSE config_file ${usr}/lib/*/sparseloopConfig.cmake)
if(NOT config_file)
  message(FATAL_ERROR "${deb} has no sparseloopConfig.cmake under /usr/lib")
endif()
if(HAVE_ROS)
  list(APPEND expected bin/sparseloop_node share/sparseloop/package.xml
    share/sparseloop/launch/sparseloop.launch share/sparseloop/sparseloop_node)
endif()
foreach(f IN LISTS expected)
  if(NOT EXISTS ${usr}/${f})
    message(FATAL_ERROR "${deb} lacks /usr/${f}")
  endif()
endforeach()
file(GLOB python_ext ${usr}/lib/python3/dist-packages/sparseloop/_sparseloop*.so)
if(NOT python_ext)
  message(FATAL_ERROR "${deb} lacks the compiled Python module")
endif()

run(${usr}/bin/sparseloop --version)
if(NOT out MATCHES "${VERSION}")
  message(FATAL_ERROR "the packaged CLI's --version does not name ${VERSION}: ${out}")
endif()
run(${CMAKE_COMMAND} -E env PYTHONPATH=${usr}/lib/python3/dist-packages
  ${PYTHON} -c "import os, sparseloop\nprint(os.path.dirname(sparseloop.__file__))")
string(STRIP "${out}" imported_from)
file(REAL_PATH ${usr}/lib/python3/dist-packages/sparseloop expected_from)
file(REAL_PATH ${imported_from} imported_from)
if(NOT imported_from STREQUAL expected_from)
  message(FATAL_ERROR "python imported sparseloop from ${imported_from}, not the package")
endif()

sparseloop_build_consumer(${usr} ${work}/consumer)

# dpkg's own verdict on this machine (needs root for dpkg's lock; changes nothing: --no-act).
execute_process(COMMAND id -u OUTPUT_VARIABLE uid OUTPUT_STRIP_TRAILING_WHITESPACE)
if(uid STREQUAL "0")
  run(dpkg --no-act --install ${deb})
  message(STATUS "dpkg --no-act --install: ${out}")
endif()
message(STATUS "package ok: ${deb}")
