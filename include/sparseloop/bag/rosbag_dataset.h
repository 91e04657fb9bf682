#pragma once
// The "rosbag:" dataset kind: a ROS 1 bag (format 2.0, indexed) as a Dataset. Built when ROS is
// found (SPARSELOOP_WITH_ROS, cmake/SparseloopRos.cmake); `detect` and `run` reach it through
// OpenDatasetSpec (pipeline/dataset_source.h).
//
//   rosbag:FILE.bag?image=/cam0/image_raw&pose=/vslam/pose&camera_info=/cam0/camera_info&gt=/gt
//
//   image        (required) sensor_msgs/Image (mono8, 8UC1, mono16, 16UC1, bgr8, rgb8, bgra8,
//                rgba8) or sensor_msgs/CompressedImage (anything OpenCV decodes)
//   camera_info  sensor_msgs/CameraInfo for the intrinsics (K, plumb_bob or equidistant D);
//                default: the image topic's sibling ".../camera_info" when the bag has it.
//                DatasetOptions::intrinsics (--intrinsics) overrides it.
//   pose         raw vSLAM poses, world_from_cam: geometry_msgs/PoseStamped,
//                PoseWithCovarianceStamped, TransformStamped or nav_msgs/Odometry -> Dataset::
//                raw_poses (associated with frames by stamp, like a TUM --poses file)
//   gt           ground truth, same types -> DatasetFrame::gt_world_from_cam (nearest stamp
//                within DatasetOptions::rosbag_max_dt); DatasetOptions::poses (a file) overrides.
//
// Frames are the image messages in header-stamp order (a bag recorded out of order is sorted,
// with a warning); DatasetFrame::index is that order, timestamp the header stamp in seconds.
// Images are decoded when the pipeline asks for them (Dataset::image_reader), not at opening.
// Errors: std::invalid_argument for a bad spec (unknown key, no image topic); FileError naming the
// bag for a missing, unindexed (cut short) or unreadable bag, a topic it does not have (the
// message lists those it has), a topic of the wrong type, and a message that cannot be
// deserialised or decoded (its topic and 0-based index on that topic).
#include <string>

#include "sparseloop/io/dataset.h"

namespace sparseloop {

// spec = "rosbag:FILE.bag?key=value&...".
Dataset OpenRosbagDataset(const std::string& spec, const DatasetOptions& options = {});

}  // namespace sparseloop
