#include "sparseloop/pipeline/dataset_source.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "sparseloop/io/rosbag_spec.h"

#ifdef SPARSELOOP_HAVE_ROSBAG
#include "sparseloop/bag/rosbag_dataset.h"
#endif

namespace sparseloop {

bool HaveRosbagDatasets() {
#ifdef SPARSELOOP_HAVE_ROSBAG
  return true;
#else
  return false;
#endif
}

Dataset OpenDatasetSpec(const std::string& spec, const DatasetOptions& options) {
  if (IsRosbagSpec(spec)) {
#ifdef SPARSELOOP_HAVE_ROSBAG
    return OpenRosbagDataset(spec, options);
#else
    throw std::invalid_argument(fmt::format(
        "'{}': this sparseloop was built without ROS (SPARSELOOP_WITH_ROS; scripts/setup installs "
        "librosbag-storage-dev), so it cannot read rosbag: datasets",
        spec));
#endif
  }
  return OpenDataset(spec, options);
}

namespace {

// The reason `path` cannot be opened for reading; empty when it can.
std::string OpenProblem(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::strerror(errno);
  ::close(fd);
  return {};
}

}  // namespace

std::string ImageReadProblem(const std::filesystem::path& path) {
  const std::string problem = OpenProblem(path);
  return problem.empty() ? "not a decodable image" : problem;
}

cv::Mat ReadFrameGray(const Dataset& dataset, const DatasetFrame& frame) {
  if (!dataset.image_reader) {
    if (!OpenProblem(frame.image_path).empty()) return {};
    return cv::imread(frame.image_path.string(), cv::IMREAD_GRAYSCALE);
  }
  GrayImage image = dataset.image_reader->ReadGray(frame);
  return cv::Mat(image.height, image.width, CV_8UC1, image.pixels.data()).clone();
}

}  // namespace sparseloop
