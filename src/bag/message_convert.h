#pragma once
// The plain ROS messages of bag_messages.h as sparseloop types: one conversion for the rosbag:
// dataset kind (rosbag_dataset.cc) and the ROS node (src/ros). Errors are MessageError (what was
// expected, what came); the caller adds the file, topic and message index.
#include <string>

#include <opencv2/core/mat.hpp>

#include "bag/bag_messages.h"
#include "sparseloop/core/camera.h"
#include "sparseloop/core/rigid3.h"

namespace sparseloop::bag_internal {

struct MessageError {
  std::string expected;
  std::string got;
};

// CV_8UC1 pixels of a sensor_msgs/Image (mono8, 8UC1, mono16, 16UC1 scaled by 1/256, bgr8, rgb8,
// 8UC3, bgra8, rgba8, 8UC4; any row step; either endianness) or CompressedImage (what OpenCV
// decodes).
cv::Mat DecodeGray(const ImageData& m);

// fx fy cx cy and size of a CameraInfo; its distortion when non-zero (plumb_bob / radtan or
// equidistant). Checked (CameraIntrinsics::Check).
CameraIntrinsics IntrinsicsFromCameraInfo(const CameraInfoMessage& c);

// The pose; the quaternion must be unit within 1e-3 (normalised).
Rigid3d PoseOf(const PoseMessage& m);

}  // namespace sparseloop::bag_internal
