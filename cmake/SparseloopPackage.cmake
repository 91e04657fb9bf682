# The Debian package: `cpack -G DEB` in a build folder (or scripts/package) writes
# sparseloop_<version>_amd64.deb with everything `cmake --install` puts under /usr: the CLI, the
# static libraries, headers and CMake config (find_package(sparseloop)), the Python module
# (/usr/lib/python3/dist-packages/sparseloop), the ROS 1 node with its ROS package folder
# (/usr/share/sparseloop) and the docs (/usr/share/doc/sparseloop).
# Depends: the shared libraries the binaries link (dpkg-shlibdeps), plus the -dev packages a
# consumer of the static libraries links through sparseloopConfig.cmake (one list, below).
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR} FILES_MATCHING PATTERN "*.md"
  PATTERN "*.png" PATTERN "*.svg")

set(SPARSELOOP_DEB_DEV_DEPENDS
  libeigen3-dev libopencv-dev libceres-dev libfmt-dev libspdlog-dev libsqlite3-dev
  nlohmann-json3-dev libfaiss-dev libblas-dev liblapack-dev)
set(SPARSELOOP_DEB_RUNTIME_DEPENDS python3 python3-numpy python3-matplotlib)
if(SPARSELOOP_HAVE_ROS)
  # sparseloopTargets.cmake names the ROS libraries by full path (cmake/SparseloopRos.cmake).
  list(APPEND SPARSELOOP_DEB_DEV_DEPENDS librosbag-storage-dev libroslz4-dev
    libboost-filesystem-dev libroscpp-core-dev libconsole-bridge-dev)
endif()
list(JOIN SPARSELOOP_DEB_DEV_DEPENDS ", " _sl_dev)
list(JOIN SPARSELOOP_DEB_RUNTIME_DEPENDS ", " _sl_run)

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME sparseloop)
set(CPACK_PACKAGE_VENDOR "sparseloop developers")
set(CPACK_PACKAGE_CONTACT "sparseloop developers <dev@sparseloop.invalid>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Loop closure for monocular visual SLAM (library, CLI, Python, ROS 1 node)")
set(CPACK_PACKAGE_DESCRIPTION
  "sparseloop takes the keyframes a monocular vSLAM produces, detects revisits with K informative\n\
ORB features per keyframe inside a geometric search area, verifies them and corrects the\n\
trajectory with a Sim(3) pose graph (Ceres).")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # executables and the Python module; static libraries keep their symbols
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # sparseloop_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "${_sl_dev}, ${_sl_run}")
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://sparseloop.invalid")
set(CPACK_DEBIAN_COMPRESSION_TYPE zstd)  # dpkg reads it since 1.21.18 (bookworm: 1.21.22); fast
set(CPACK_THREADS 0)  # every core for the compression
set(CPACK_PACKAGE_DIRECTORY ${CMAKE_BINARY_DIR}/package)
set(CPACK_RESOURCE_FILE_LICENSE ${PROJECT_SOURCE_DIR}/LICENSE)
include(CPack)
