#pragma once
// The ROS side of the rosbag: dataset kind, as plain structs. bag_messages.cc is the only file
// that includes ROS headers (compiled as C++17: ROS 1 message headers do not compile as C++20,
// cmake/SparseloopRos.cmake); this header is C++17 and std-only so that both sides include it.
//
// Every error is a sparseloop::FileError naming the bag file, with the topic and the message
// index (0-based, in bag order on that topic) in its text.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace sparseloop::bag_internal {

struct TopicInfo {
  std::string topic;
  std::string type;  // "sensor_msgs/Image", ...
  size_t messages = 0;
};

// The header of one image message (no pixels), in bag order.
struct ImageHeader {
  int64_t index = 0;        // 0-based position among the topic's messages
  double stamp = 0.0;       // header.stamp, seconds
  bool compressed = false;  // sensor_msgs/CompressedImage
  std::string encoding;     // Image: encoding ("mono8", ...); CompressedImage: format
  // Image only (0 for compressed): uint32 in the message, kept whole so that a size beyond int
  // is refused as given (4000000000, not -294967296).
  int64_t width = 0;
  int64_t height = 0;
};

// One image message's content.
struct ImageData {
  ImageHeader header;
  int64_t step = 0;           // bytes per row (Image; uint32 in the message)
  bool big_endian = false;    // Image
  std::vector<uint8_t> data;  // pixels (Image) or the encoded file (CompressedImage)
};

// geometry_msgs/PoseStamped, PoseWithCovarianceStamped, TransformStamped or nav_msgs/Odometry.
struct PoseMessage {
  int64_t index = 0;
  double stamp = 0.0;  // header.stamp, seconds
  double position[3] = {0, 0, 0};
  double orientation_xyzw[4] = {0, 0, 0, 1};
  // PoseWithCovarianceStamped / Odometry: the pose's 6x6 covariance, row-major, in ROS order
  // (x, y, z, rotation about X, Y, Z of the header frame); all zero when the sender gives none.
  double covariance[36] = {};
};

// sensor_msgs/CameraInfo (first message of the topic).
struct CameraInfoMessage {
  int64_t width = 0;  // uint32 in the message, kept whole (see ImageHeader)
  int64_t height = 0;
  std::string distortion_model;  // "plumb_bob", "rational_polynomial", "equidistant", ""
  std::vector<double> d;
  double k[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
};

// An open bag (rosbag::Bag). Not thread-safe: callers serialise.
class BagReader {
 public:
  // FileError when the file is missing, not a bag, unindexed or cut short.
  explicit BagReader(const std::string& path);
  ~BagReader();
  BagReader(const BagReader&) = delete;
  BagReader& operator=(const BagReader&) = delete;

  const std::string& path() const { return path_; }
  std::vector<TopicInfo> Topics() const;
  // Headers of every message on an image topic (Image or CompressedImage).
  std::vector<ImageHeader> ImageHeaders(const std::string& topic) const;
  // The index-th message of an image topic.
  ImageData ReadImage(const std::string& topic, int64_t index) const;
  std::vector<PoseMessage> Poses(const std::string& topic) const;
  std::optional<CameraInfoMessage> FirstCameraInfo(const std::string& topic) const;

 private:
  struct Impl;
  std::string path_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sparseloop::bag_internal
