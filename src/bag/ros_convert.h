#pragma once
// ROS 1 message objects as the plain structs of bag_messages.h: one conversion for bags
// (bag_messages.cc) and live topics (src/ros). Includes ROS headers: C++17 files only
// (cmake/SparseloopRos.cmake).
#include <algorithm>
#include <cstdint>

#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "bag/bag_messages.h"

namespace sparseloop::bag_internal {

inline ImageHeader HeaderOf(const sensor_msgs::Image& msg, int64_t index) {
  ImageHeader h;
  h.index = index;
  h.stamp = msg.header.stamp.toSec();
  h.encoding = msg.encoding;
  h.width = static_cast<int64_t>(msg.width);
  h.height = static_cast<int64_t>(msg.height);
  return h;
}

inline ImageHeader HeaderOf(const sensor_msgs::CompressedImage& msg, int64_t index) {
  ImageHeader h;
  h.index = index;
  h.stamp = msg.header.stamp.toSec();
  h.compressed = true;
  h.encoding = msg.format;
  return h;
}

inline ImageData ToImageData(const sensor_msgs::Image& msg, int64_t index) {
  ImageData out;
  out.header = HeaderOf(msg, index);
  out.step = static_cast<int64_t>(msg.step);
  out.big_endian = msg.is_bigendian != 0;
  out.data = msg.data;
  return out;
}

inline ImageData ToImageData(const sensor_msgs::CompressedImage& msg, int64_t index) {
  ImageData out;
  out.header = HeaderOf(msg, index);
  out.data = msg.data;
  return out;
}

// Position and orientation of any pose-carrying message (Pose, Transform: x y z members).
template <typename Position, typename Orientation>
PoseMessage ToPoseMessage(int64_t index, const ros::Time& stamp, const Position& position,
                          const Orientation& orientation) {
  PoseMessage p;
  p.index = index;
  p.stamp = stamp.toSec();
  p.position[0] = position.x, p.position[1] = position.y, p.position[2] = position.z;
  p.orientation_xyzw[0] = orientation.x, p.orientation_xyzw[1] = orientation.y;
  p.orientation_xyzw[2] = orientation.z, p.orientation_xyzw[3] = orientation.w;
  return p;
}

inline CameraInfoMessage ToCameraInfo(const sensor_msgs::CameraInfo& msg) {
  CameraInfoMessage c;
  c.width = static_cast<int64_t>(msg.width);
  c.height = static_cast<int64_t>(msg.height);
  c.distortion_model = msg.distortion_model;
  c.d = msg.D;
  std::copy(msg.K.begin(), msg.K.end(), c.k);
  return c;
}

}  // namespace sparseloop::bag_internal
