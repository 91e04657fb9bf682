#include "sparseloop/bag/rosbag_dataset.h"

#include <algorithm>
#include <map>
#include <mutex>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/core/mat.hpp>

#include "bag/bag_messages.h"
#include "bag/message_convert.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/io/rosbag_spec.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop {

namespace fs = std::filesystem;
using bag_internal::BagReader;
using bag_internal::ImageData;
using bag_internal::ImageHeader;
using bag_internal::TopicInfo;

namespace {

// The topic must be in the bag (with the listed types); the message lists what the bag has.
const bag_internal::TopicInfo& RequireTopic(const std::vector<bag_internal::TopicInfo>& topics,
                                            const std::string& file, const std::string& topic,
                                            const std::string& what) {
  for (const auto& t : topics) {
    if (t.topic == topic) return t;
  }
  std::string have;
  for (const auto& t : topics)
    have += fmt::format("{}{} ({})", have.empty() ? "" : ", ", t.topic, t.type);
  throw FileError(file, 0, fmt::format("topic {} ({})", topic, what),
                  fmt::format("no such topic; the bag has {}", have.empty() ? "none" : have));
}

Trajectory PosesToTrajectory(const std::vector<bag_internal::PoseMessage>& messages,
                             const std::string& file, const std::string& topic) {
  Trajectory traj;
  traj.has_rotation = true;
  traj.has_timestamps = true;
  for (const auto& m : messages) {
    try {
      traj.poses.push_back(StampedPose{m.stamp, m.index, bag_internal::PoseOf(m)});
    } catch (const bag_internal::MessageError& e) {
      throw FileError(
          file, 0, fmt::format("{} in message {} of topic {}", e.expected, m.index, topic), e.got);
    }
  }
  std::stable_sort(
      traj.poses.begin(), traj.poses.end(),
      [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  return traj;
}

CameraIntrinsics IntrinsicsFromCameraInfo(const bag_internal::CameraInfoMessage& c,
                                          const std::string& file, const std::string& topic) {
  try {
    return bag_internal::IntrinsicsFromCameraInfo(c);
  } catch (const bag_internal::MessageError& e) {
    throw FileError(file, 0, fmt::format("{} in topic {} (message 0)", e.expected, topic), e.got);
  }
}

// Decodes the frames' messages on demand; keeps the bag open.
class BagImageReader : public DatasetImageReader {
 public:
  BagImageReader(std::shared_ptr<BagReader> bag, std::string topic, std::vector<int64_t> message)
      : bag_(std::move(bag)), topic_(std::move(topic)), message_(std::move(message)) {}

  GrayImage ReadGray(const DatasetFrame& frame) const override {
    SL_CHECK_MSG(frame.index >= 0 && static_cast<size_t>(frame.index) < message_.size(),
                 "frame {} is not a frame of {}", frame.index, bag_->path());
    const int64_t index = message_[frame.index];
    ImageData m;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      m = bag_->ReadImage(topic_, index);
    }
    const auto fail = [&](const std::string& expected, const std::string& got) {
      return FileError(bag_->path(), 0,
                       fmt::format("{} in message {} of topic {}", expected, index, topic_), got);
    };
    cv::Mat gray;
    try {
      gray = bag_internal::DecodeGray(m);
    } catch (const bag_internal::MessageError& e) {
      throw fail(e.expected, e.got);
    }
    if (size_.width == 0) {
      size_ = {gray.cols, gray.rows};
    } else if (gray.cols != size_.width || gray.rows != size_.height) {
      throw fail(fmt::format("an image of {}x{} like the earlier ones", size_.width, size_.height),
                 fmt::format("{}x{}", gray.cols, gray.rows));
    }
    GrayImage out;
    out.width = gray.cols;
    out.height = gray.rows;
    out.pixels.assign(gray.datastart, gray.dataend);
    return out;
  }

  void ExpectSize(int width, int height) { size_ = {width, height}; }

 private:
  std::shared_ptr<BagReader> bag_;
  std::string topic_;
  std::vector<int64_t> message_;  // bag message index of each frame
  mutable std::mutex mutex_;
  mutable ImageSize size_;
};

// The image headers in stamp order as the dataset's frames (index, stamp, a name for messages),
// each raw image checked for its size; returns the raw images' common size (none when every image
// is compressed) and the bag message of each frame.
std::optional<ImageSize> FramesFromImages(const RosbagSpec& s, std::vector<ImageHeader> headers,
                                          Dataset* d, std::vector<int64_t>* message_of_frame) {
  if (headers.empty()) {
    throw FileError(s.file, 0, fmt::format("at least one image on topic {}", s.image), "none");
  }
  const auto by_stamp = [](const ImageHeader& a, const ImageHeader& b) {
    return a.stamp < b.stamp;
  };
  if (!std::is_sorted(headers.begin(), headers.end(), by_stamp)) {
    Logger().warn("{}: images on {} are not in stamp order; frames follow the stamps", s.file,
                  s.image);
    std::stable_sort(headers.begin(), headers.end(), by_stamp);
  }
  std::optional<ImageSize> size;
  for (size_t i = 0; i < headers.size(); ++i) {
    const ImageHeader& h = headers[i];
    if (i > 0 && h.stamp == headers[i - 1].stamp) {
      throw FileError(s.file, 0,
                      fmt::format("distinct image stamps on topic {} (messages {} and {})", s.image,
                                  headers[i - 1].index, h.index),
                      fmt::format("both {:.9f} s", h.stamp));
    }
    if (!h.compressed) {
      if (h.width < kMinImageSide || h.height < kMinImageSide || h.width > kMaxImagePixels ||
          h.height > kMaxImagePixels || h.width * h.height > kMaxImagePixels) {
        throw FileError(s.file, 0,
                        fmt::format("an image of {0}x{0} to {1} pixels in message {2} of topic {3}",
                                    kMinImageSide, kMaxImagePixels, h.index, s.image),
                        fmt::format("{}x{}", h.width, h.height));
      }
      if (!size) size = ImageSize{static_cast<int>(h.width), static_cast<int>(h.height)};
      if (h.width != size->width || h.height != size->height) {
        throw FileError(s.file, 0,
                        fmt::format("every image {}x{} in topic {} (message {})", size->width,
                                    size->height, s.image, h.index),
                        fmt::format("{}x{}", h.width, h.height));
      }
    }
    DatasetFrame f;
    f.index = static_cast<int64_t>(i);
    f.timestamp = h.stamp;
    // Names the frame in messages and output files (frames.csv): FILE.bag/<topic>/<message>.
    f.image_path = fs::path(s.file) / s.image.substr(1) / fmt::format("{:06d}", h.index);
    d->frames.push_back(std::move(f));
    message_of_frame->push_back(h.index);
  }
  return size;
}

// Intrinsics: --intrinsics, else camera_info (explicit or the image topic's sibling); checked
// against the images' size and for a principal point inside the image.
void ResolveIntrinsics(const std::string& spec, const RosbagSpec& s,
                       const std::vector<TopicInfo>& topics, BagReader& bag,
                       const DatasetOptions& options, const std::optional<ImageSize>& size,
                       Dataset* d) {
  std::string info_topic = s.camera_info;
  if (info_topic.empty()) {
    const std::string sibling = s.image.substr(0, s.image.rfind('/')) + "/camera_info";
    for (const auto& t : topics) {
      if (t.topic == sibling) info_topic = sibling;
    }
  }
  if (options.intrinsics) {
    d->intrinsics = *options.intrinsics;
    d->intrinsics_source = options.intrinsics_name;
  } else if (!info_topic.empty()) {
    RequireTopic(topics, s.file, info_topic, "sensor_msgs/CameraInfo");
    const auto info = bag.FirstCameraInfo(info_topic);
    if (!info) throw FileError(s.file, 0, fmt::format("a message on topic {}", info_topic), "none");
    d->intrinsics = IntrinsicsFromCameraInfo(*info, s.file, info_topic);
    d->intrinsics_source = fmt::format("{} topic {}", s.file, info_topic);
  } else {
    throw std::invalid_argument(fmt::format(
        "{} needs intrinsics: a camera_info=TOPIC in the spec, a {} topic in the bag, or {}", spec,
        s.image.substr(0, s.image.rfind('/')) + "/camera_info", options.intrinsics_name));
  }
  CameraIntrinsics& k = d->intrinsics;
  if (size) {
    if (k.width == 0 || k.height == 0) {
      k.width = size->width;
      k.height = size->height;
    } else if (k.width != size->width || k.height != size->height) {
      throw FileError(s.file, 0,
                      fmt::format("images of {}x{} on topic {} (the size of {})", k.width, k.height,
                                  s.image, d->intrinsics_source),
                      fmt::format("{}x{}", size->width, size->height));
    }
  }
  if (k.width > 0 && k.height > 0 && !(k.cx > 0 && k.cx < k.width && k.cy > 0 && k.cy < k.height)) {
    throw std::invalid_argument(fmt::format("{}: principal point ({}, {}) outside the {}x{} image",
                                            d->intrinsics_source, k.cx, k.cy, k.width, k.height));
  }
}

// Ground truth: DatasetOptions::poses (a timestamped file with orientations), else the spec's
// gt=TOPIC; attached to the frames by time. Returns the frames that got a GT pose.
size_t AttachRosbagGt(const RosbagSpec& s, const std::vector<TopicInfo>& topics, BagReader& bag,
                      const DatasetOptions& options, Dataset* d) {
  if (!options.poses.empty()) {
    d->gt_path = options.poses;
    Trajectory gt = ReadTrajectory(options.poses);
    if (!gt.has_rotation) {
      throw FileError(options.poses.string(), 0, "a ground-truth trajectory with orientations",
                      "a positions-only file");
    }
    if (!gt.has_timestamps) {
      throw FileError(options.poses.string(), 0,
                      "a timestamped ground truth (TUM or EuRoC) for a rosbag: dataset",
                      "a file without timestamps");
    }
    return AttachGtByTime(d->frames, gt, options.rosbag_max_dt);
  }
  if (s.gt.empty()) return 0;
  RequireTopic(topics, s.file, s.gt, "ground-truth poses");
  d->gt_path = s.file;
  return AttachGtByTime(d->frames, PosesToTrajectory(bag.Poses(s.gt), s.file, s.gt),
                        options.rosbag_max_dt);
}

}  // namespace

Dataset OpenRosbagDataset(const std::string& spec, const DatasetOptions& options) {
  options.Check();
  const RosbagSpec s = ParseRosbagSpec(spec);
  std::error_code ec;
  if (!fs::is_regular_file(s.file, ec)) throw FileError(s.file, 0, "a ROS bag file", "missing");
  auto bag = std::make_shared<BagReader>(s.file);
  const auto topics = bag->Topics();

  Dataset d;
  d.kind = "rosbag";
  d.root = s.file;
  RequireTopic(topics, s.file, s.image, "sensor_msgs/Image or sensor_msgs/CompressedImage");
  std::vector<int64_t> message_of_frame;
  const std::optional<ImageSize> size =
      FramesFromImages(s, bag->ImageHeaders(s.image), &d, &message_of_frame);
  ResolveIntrinsics(spec, s, topics, *bag, options, size, &d);
  auto reader = std::make_shared<BagImageReader>(bag, s.image, std::move(message_of_frame));
  if (size) reader->ExpectSize(size->width, size->height);
  d.image_reader = std::move(reader);

  if (!s.pose.empty()) {
    RequireTopic(topics, s.file, s.pose, "raw vSLAM poses");
    d.raw_poses = PosesToTrajectory(bag->Poses(s.pose), s.file, s.pose);
    if (d.raw_poses.empty()) {
      throw FileError(s.file, 0, fmt::format("at least one pose on topic {}", s.pose), "none");
    }
    d.raw_poses_source = fmt::format("{} topic {}", s.file, s.pose);
  }
  const size_t attached = AttachRosbagGt(s, topics, *bag, options, &d);
  Logger().info("rosbag dataset {}: {} frames from {}, {} raw poses, ground truth for {}", s.file,
                d.frames.size(), s.image, d.raw_poses.size(), attached);
  return d;
}

}  // namespace sparseloop
