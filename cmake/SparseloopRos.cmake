# ROS 1 as Debian bookworm ships it (librosbag-storage-dev, the *-msgs-dev packages): pkg-config
# files and plain libraries, no catkin. Sets SPARSELOOP_HAVE_ROS and, when ON:
#   SPARSELOOP_ROS_BAG_LIBS   full paths of librosbag_storage and what reading/writing a bag needs
#   SPARSELOOP_ROS_INCLUDES   include folders (bag.h pulls Debian's pluginlib/class_loader headers)
# Full paths (not imported targets), so that the installed sparseloopTargets.cmake needs nothing
# of ROS to be found again.
#
# ROS 1 message headers use std::allocator<void>::rebind, which C++20 removed: every file that
# includes a ROS header is compiled as C++17 (sparseloop_ros_cxx17) and talks to the C++20 library
# through plain structs (src/bag/bag_messages.h).
#
# Off with sanitizers: ROS's uninstrumented libraries (log4cxx, boost threads, XmlRpc) leak at exit
# and race in ways the ASan/TSan stages would report as ours.
set(SPARSELOOP_HAVE_ROS OFF)
if(NOT SPARSELOOP_WITH_ROS)
  return()
endif()
if(SPARSELOOP_SANITIZE OR SPARSELOOP_BUILD_FUZZERS)
  message(STATUS "sparseloop: ROS parts off (sanitizer / fuzzer build)")
  return()
endif()
find_package(PkgConfig QUIET)
if(NOT PkgConfig_FOUND)
  message(STATUS "sparseloop: ROS parts off (no pkg-config)")
  return()
endif()
pkg_check_modules(SL_ROS_MSGS QUIET roscpp_serialization rostime cpp_common console_bridge
  sensor_msgs geometry_msgs nav_msgs)
find_library(SL_ROSBAG_STORAGE_LIB rosbag_storage)
find_library(SL_ROSLZ4_LIB roslz4)
find_library(SL_BOOST_FS_LIB boost_filesystem)
find_path(SL_PLUGINLIB_INCLUDE pluginlib/class_loader.hpp PATH_SUFFIXES pluginlib)
find_path(SL_ROSBAG_INCLUDE rosbag/bag.h)
set(_sl_ros_missing)
foreach(v SL_ROS_MSGS_FOUND SL_ROSBAG_STORAGE_LIB SL_ROSLZ4_LIB SL_BOOST_FS_LIB
          SL_PLUGINLIB_INCLUDE SL_ROSBAG_INCLUDE)
  if(NOT ${v})
    list(APPEND _sl_ros_missing ${v})
  endif()
endforeach()
if(_sl_ros_missing AND "$ENV{CI}" STREQUAL "true")
  message(FATAL_ERROR "sparseloop: CI=true needs ROS for the rosbag: tests (not found: ${_sl_ros_missing}; run scripts/setup)")
elseif(_sl_ros_missing)
  message(STATUS "sparseloop: ROS parts off (not found: ${_sl_ros_missing}; scripts/setup installs them)")
  return()
endif()
set(SPARSELOOP_HAVE_ROS ON)
set(SPARSELOOP_ROS_INCLUDES ${SL_ROSBAG_INCLUDE} ${SL_PLUGINLIB_INCLUDE})
foreach(dep class_loader rcpputils rcutils ament_index_cpp)
  if(EXISTS /usr/include/${dep})
    list(APPEND SPARSELOOP_ROS_INCLUDES /usr/include/${dep})
  endif()
endforeach()
set(SPARSELOOP_ROS_BAG_LIBS ${SL_ROSBAG_STORAGE_LIB} ${SL_ROSLZ4_LIB} ${SL_BOOST_FS_LIB}
  ${SL_ROS_MSGS_LINK_LIBRARIES})
message(STATUS "sparseloop: ROS 1 found: rosbag: datasets are built")

# An object library of C++17 files that include ROS headers (see above). They may include
# sparseloop's plain-struct headers but no other sparseloop header.
function(sparseloop_ros_cxx17 target)
  set_target_properties(${target} PROPERTIES CXX_STANDARD 17 CXX_STANDARD_REQUIRED ON
    CXX_EXTENSIONS OFF POSITION_INDEPENDENT_CODE ON)
  target_include_directories(${target} SYSTEM PRIVATE ${SPARSELOOP_ROS_INCLUDES}
    ${SL_ROS_MSGS_INCLUDE_DIRS})
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR}/include ${PROJECT_SOURCE_DIR}/src)
endfunction()

# The node (src/ros, sparseloop_node) needs roscpp and a few more message packages besides the bag
# ones: SPARSELOOP_HAVE_ROS_NODE, SPARSELOOP_ROS_NODE_LIBS, SPARSELOOP_ROS_NODE_INCLUDES.
set(SPARSELOOP_HAVE_ROS_NODE OFF)
pkg_check_modules(SL_ROS_NODE QUIET roscpp tf2_ros std_srvs std_msgs visualization_msgs
  diagnostic_msgs)
if(NOT SL_ROS_NODE_FOUND AND "$ENV{CI}" STREQUAL "true")
  message(FATAL_ERROR "sparseloop: CI=true needs the ROS node packages (roscpp tf2_ros std_srvs "
                      "visualization_msgs; run scripts/setup)")
elseif(NOT SL_ROS_NODE_FOUND)
  message(STATUS "sparseloop: ROS node off (roscpp / tf2_ros / std_srvs / visualization_msgs not "
                 "found; scripts/setup installs them)")
  return()
endif()
set(SPARSELOOP_HAVE_ROS_NODE ON)
set(SPARSELOOP_ROS_NODE_LIBS ${SL_ROS_NODE_LINK_LIBRARIES} ${SPARSELOOP_ROS_BAG_LIBS})
set(SPARSELOOP_ROS_NODE_INCLUDES ${SL_ROS_NODE_INCLUDE_DIRS})
message(STATUS "sparseloop: ROS 1 roscpp found: sparseloop_node is built")
