// The ROS side of the rosbag: dataset kind (bag_messages.h). C++17: ROS 1 message headers do not
// compile as C++20. Reads with rosbag_storage; every message is deserialised inside a try block
// so that a malformed or cut message names the bag, the topic and the message index.
#include "bag/bag_messages.h"
#include "bag/ros_convert.h"

#include <algorithm>
#include <exception>

#include <fmt/format.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "sparseloop/core/error.h"

namespace sparseloop::bag_internal {

namespace {

constexpr const char* kImage = "sensor_msgs/Image";
constexpr const char* kCompressedImage = "sensor_msgs/CompressedImage";
constexpr const char* kCameraInfo = "sensor_msgs/CameraInfo";
constexpr const char* kPoseStamped = "geometry_msgs/PoseStamped";
constexpr const char* kPoseWithCovariance = "geometry_msgs/PoseWithCovarianceStamped";
constexpr const char* kTransformStamped = "geometry_msgs/TransformStamped";
constexpr const char* kOdometry = "nav_msgs/Odometry";

std::string TypesList(const std::vector<std::string>& types) {
  std::string out;
  for (size_t i = 0; i < types.size(); ++i)
    out += (i ? (i + 1 == types.size() ? " or " : ", ") : "") + types[i];
  return out;
}

}  // namespace

struct BagReader::Impl {
  rosbag::Bag bag;
  // Sequential access to one image topic without rescanning: the view and where it stands.
  std::string cursor_topic;
  std::unique_ptr<rosbag::View> cursor_view;
  rosbag::View::iterator cursor;
  int64_t cursor_index = -1;  // index of the message *cursor points at
};

BagReader::BagReader(const std::string& path) : path_(path), impl_(std::make_unique<Impl>()) {
  try {
    impl_->bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagUnindexedException& e) {
    throw FileError(path, 0,
                    "an indexed ROS bag (a recording cut short has no index: 'rosbag reindex' "
                    "may recover it)",
                    "a bag without index");
  } catch (const std::exception& e) {
    throw FileError(path, 0,
                    "a readable ROS bag (format 2.0, indexed: a recording cut short has no index, "
                    "'rosbag reindex' may recover it)",
                    e.what());
  }
}

BagReader::~BagReader() = default;

std::vector<TopicInfo> BagReader::Topics() const {
  std::vector<TopicInfo> out;
  try {
    rosbag::View view(impl_->bag);
    for (const rosbag::ConnectionInfo* c : view.getConnections()) {
      auto it = std::find_if(out.begin(), out.end(),
                             [&](const TopicInfo& t) { return t.topic == c->topic; });
      if (it == out.end()) {
        out.push_back({c->topic, c->datatype, 0});
        it = std::prev(out.end());
      }
      it->messages += rosbag::View(impl_->bag, rosbag::TopicQuery(c->topic)).size();
    }
  } catch (const std::exception& e) {
    throw FileError(path_, 0, "a readable ROS bag index", e.what());
  }
  std::sort(out.begin(), out.end(),
            [](const TopicInfo& a, const TopicInfo& b) { return a.topic < b.topic; });
  return out;
}

namespace {

// Calls fn(message, index) for each message of `topic`, checking its type against `types`;
// deserialisation errors become FileErrors naming topic and index.
template <typename Fn>
void ForEach(rosbag::Bag& bag, const std::string& path, const std::string& topic,
             const std::vector<std::string>& types, Fn&& fn) {
  int64_t index = 0;
  std::string type;
  try {
    rosbag::View view(bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& m : view) {
      type = m.getDataType();
      if (std::find(types.begin(), types.end(), type) == types.end()) {
        throw FileError(path, 0,
                        fmt::format("{} on topic {} (message {})", TypesList(types), topic, index),
                        type);
      }
      fn(m, index);
      ++index;
    }
  } catch (const FileError&) {
    throw;
  } catch (const std::exception& e) {
    throw FileError(path, 0,
                    fmt::format("a complete {} as message {} of topic {}",
                                type.empty() ? TypesList(types) : type, index, topic),
                    e.what());
  }
}

ImageHeader HeaderOfMessage(const rosbag::MessageInstance& m, int64_t index) {
  if (m.getDataType() == kImage) return HeaderOf(*m.instantiate<sensor_msgs::Image>(), index);
  return HeaderOf(*m.instantiate<sensor_msgs::CompressedImage>(), index);
}

}  // namespace

std::vector<ImageHeader> BagReader::ImageHeaders(const std::string& topic) const {
  std::vector<ImageHeader> out;
  ForEach(impl_->bag, path_, topic, {kImage, kCompressedImage},
          [&](const rosbag::MessageInstance& m, int64_t index) {
            out.push_back(HeaderOfMessage(m, index));
          });
  return out;
}

ImageData BagReader::ReadImage(const std::string& topic, int64_t index) const {
  Impl& s = *impl_;
  try {
    if (s.cursor_topic != topic || !s.cursor_view || index < s.cursor_index) {
      s.cursor_topic = topic;
      s.cursor_view = std::make_unique<rosbag::View>(s.bag, rosbag::TopicQuery(topic));
      s.cursor = s.cursor_view->begin();
      s.cursor_index = 0;
    }
    while (s.cursor != s.cursor_view->end() && s.cursor_index < index) {
      ++s.cursor;
      ++s.cursor_index;
    }
    if (s.cursor == s.cursor_view->end()) {
      throw FileError(path_, 0, fmt::format("message {} on topic {}", index, topic), "fewer");
    }
    const rosbag::MessageInstance& m = *s.cursor;
    ImageData out = m.getDataType() == kImage
                        ? ToImageData(*m.instantiate<sensor_msgs::Image>(), index)
                        : ToImageData(*m.instantiate<sensor_msgs::CompressedImage>(), index);
    return out;
  } catch (const FileError&) {
    s.cursor_view.reset();
    throw;
  } catch (const std::exception& e) {
    s.cursor_view.reset();
    throw FileError(path_, 0,
                    fmt::format("a complete image as message {} of topic {}", index, topic),
                    e.what());
  }
}

std::vector<PoseMessage> BagReader::Poses(const std::string& topic) const {
  std::vector<PoseMessage> out;
  ForEach(
      impl_->bag, path_, topic, {kPoseStamped, kOdometry, kPoseWithCovariance, kTransformStamped},
      [&](const rosbag::MessageInstance& m, int64_t index) {
        PoseMessage p;
        const std::string& type = m.getDataType();
        if (type == kPoseStamped) {
          const auto msg = m.instantiate<geometry_msgs::PoseStamped>();
          p = ToPoseMessage(index, msg->header.stamp, msg->pose.position, msg->pose.orientation);
        } else if (type == kOdometry) {
          const auto msg = m.instantiate<nav_msgs::Odometry>();
          p = ToPoseMessage(index, msg->header.stamp, msg->pose.pose.position,
                            msg->pose.pose.orientation);
        } else if (type == kPoseWithCovariance) {
          const auto msg = m.instantiate<geometry_msgs::PoseWithCovarianceStamped>();
          p = ToPoseMessage(index, msg->header.stamp, msg->pose.pose.position,
                            msg->pose.pose.orientation);
        } else {
          const auto msg = m.instantiate<geometry_msgs::TransformStamped>();
          p = ToPoseMessage(index, msg->header.stamp, msg->transform.translation,
                            msg->transform.rotation);
        }
        out.push_back(p);
      });
  return out;
}

std::optional<CameraInfoMessage> BagReader::FirstCameraInfo(const std::string& topic) const {
  std::optional<CameraInfoMessage> out;
  try {
    rosbag::View view(impl_->bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& m : view) {
      if (m.getDataType() != kCameraInfo) {
        throw FileError(path_, 0, fmt::format("{} on topic {} (message 0)", kCameraInfo, topic),
                        m.getDataType());
      }
      out = ToCameraInfo(*m.instantiate<sensor_msgs::CameraInfo>());
      break;
    }
  } catch (const FileError&) {
    throw;
  } catch (const std::exception& e) {
    throw FileError(path_, 0,
                    fmt::format("a complete {} as message 0 of topic {}", kCameraInfo, topic),
                    e.what());
  }
  return out;
}

}  // namespace sparseloop::bag_internal
