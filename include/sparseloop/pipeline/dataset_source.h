#pragma once
// Every dataset kind behind one call, and a frame's image whatever holds it. The folder kinds are
// io's OpenDataset; "rosbag:" is the bag module's OpenRosbagDataset when the library was built
// with ROS (SPARSELOOP_WITH_ROS), otherwise std::invalid_argument saying so.
#include <string>

#include <opencv2/core.hpp>

#include "sparseloop/io/dataset.h"

namespace sparseloop {

// True when this build reads "rosbag:" datasets.
bool HaveRosbagDatasets();

// "kitti:DIR", "tum:DIR", "euroc:DIR", "images:DIR" or "rosbag:FILE.bag?image=TOPIC&...".
Dataset OpenDatasetSpec(const std::string& spec, const DatasetOptions& options = {});

// The frame's image as 8-bit gray: from Dataset::image_reader when set (FileError naming the
// message when it cannot be decoded), else cv::imread of image_path (empty when unreadable: a file
// that cannot be opened is not handed to OpenCV, which would print a warning on stderr).
cv::Mat ReadFrameGray(const Dataset& dataset, const DatasetFrame& frame);

// Why the image file at `path` gives no image: the reason it cannot be opened ("Permission
// denied", "No such file or directory", "Too many levels of symbolic links"), else "not a
// decodable image".
std::string ImageReadProblem(const std::filesystem::path& path);

}  // namespace sparseloop
