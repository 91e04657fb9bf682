# A unity build whose compile inputs do not depend on where the checkout lies, so that ccache
# (base_dir = the checkout) serves a clone at another path from the same entries.
#
# CMake's own unity build (CMAKE_UNITY_BUILD, before CMake 3.31) writes `#include "/abs/path.cc"`
# into each batch: the batch's text and the preprocessor's line markers then hold the checkout's
# path, and a second clone misses the cache on every file. Here each batch includes its sources by
# a path relative to the batch file (`#include "../../../../src/core/check.cc"`), which is the
# same in every clone whose build folder sits at the same place in it (build/, build-asan/, ...).
#
# sparseloop_unity_build() runs once, at the end of the top-level CMakeLists.txt, over every
# target of the project when SPARSELOOP_UNITY is ON: the C++ sources of a target are grouped in
# their listed order into batches of SPARSELOOP_UNITY_BATCH (8, CMake's default), the batches
# replace them in the target; a source with compile flags of its own stays on its own. Two sources of one target may then not define the same name in an
# anonymous namespace (the compiler says so).
option(SPARSELOOP_UNITY "Compile each target as batches of its sources (relocatable unity build)" OFF)
set(SPARSELOOP_UNITY_BATCH 8 CACHE STRING "Sources per unity batch")

function(_sparseloop_collect_targets dir out)
  get_property(targets DIRECTORY "${dir}" PROPERTY BUILDSYSTEM_TARGETS)
  get_property(subdirs DIRECTORY "${dir}" PROPERTY SUBDIRECTORIES)
  foreach(sub IN LISTS subdirs)
    _sparseloop_collect_targets("${sub}" sub_targets)
    list(APPEND targets ${sub_targets})
  endforeach()
  set(${out} ${targets} PARENT_SCOPE)
endfunction()

# Writes FILE with CONTENT only when it differs, so a reconfigure rebuilds nothing.
function(_sparseloop_write_if_changed file content)
  if(EXISTS "${file}")
    file(READ "${file}" old)
    if(old STREQUAL content)
      return()
    endif()
  endif()
  file(WRITE "${file}" "${content}")
endfunction()

function(_sparseloop_unity_target target)
  get_target_property(type ${target} TYPE)
  if(NOT type MATCHES "^(STATIC_LIBRARY|SHARED_LIBRARY|MODULE_LIBRARY|OBJECT_LIBRARY|EXECUTABLE)$")
    return()
  endif()
  get_target_property(sources ${target} SOURCES)
  get_target_property(source_dir ${target} SOURCE_DIR)
  get_target_property(binary_dir ${target} BINARY_DIR)
  set(unity_dir "${binary_dir}/CMakeFiles/${target}.dir/unity")
  set(kept "")
  set(batches "")
  set(content "")
  set(count 0)
  foreach(source IN LISTS sources)
    if(source MATCHES "\\$<")  # a generator expression: left to CMake
      list(APPEND kept "${source}")
      continue()
    endif()
    cmake_path(ABSOLUTE_PATH source BASE_DIRECTORY "${source_dir}" NORMALIZE
               OUTPUT_VARIABLE path)
    cmake_path(IS_PREFIX PROJECT_BINARY_DIR "${path}" generated)
    # As CMake does: a source with flags of its own is compiled on its own.
    set(own_flags FALSE)
    foreach(property COMPILE_DEFINITIONS COMPILE_OPTIONS COMPILE_FLAGS INCLUDE_DIRECTORIES
                     SKIP_UNITY_BUILD_INCLUSION)
      get_source_file_property(value "${path}" DIRECTORY "${source_dir}" ${property})
      if(value)
        set(own_flags TRUE)
      endif()
    endforeach()
    if(NOT path MATCHES "\\.(cc|cpp|cxx)$" OR generated OR own_flags OR NOT EXISTS "${path}")
      list(APPEND kept "${path}")
      continue()
    endif()
    file(RELATIVE_PATH relative "${unity_dir}" "${path}")
    string(APPEND content "#include \"${relative}\"\n")
    math(EXPR count "${count} + 1")
    if(count EQUAL SPARSELOOP_UNITY_BATCH)
      list(LENGTH batches index)
      set(batch "${unity_dir}/unity_${index}.cc")
      _sparseloop_write_if_changed("${batch}" "${content}")
      list(APPEND batches "${batch}")
      set(content "")
      set(count 0)
    endif()
  endforeach()
  if(count GREATER 0)
    list(LENGTH batches index)
    set(batch "${unity_dir}/unity_${index}.cc")
    _sparseloop_write_if_changed("${batch}" "${content}")
    list(APPEND batches "${batch}")
  endif()
  if(batches)
    set_property(TARGET ${target} PROPERTY SOURCES ${kept} ${batches})
  endif()
endfunction()

function(sparseloop_unity_build)
  if(NOT SPARSELOOP_UNITY)
    return()
  endif()
  _sparseloop_collect_targets("${PROJECT_SOURCE_DIR}" targets)
  foreach(target IN LISTS targets)
    _sparseloop_unity_target(${target})
  endforeach()
endfunction()
