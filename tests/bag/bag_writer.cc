#include "bag/bag_writer.h"

#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

namespace sparseloop::test {

struct TestBagWriter::Impl {
  rosbag::Bag bag;
};

TestBagWriter::TestBagWriter(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->bag.open(path, rosbag::bagmode::Write);
}

TestBagWriter::~TestBagWriter() { Close(); }

void TestBagWriter::Close() {
  if (impl_->bag.isOpen()) impl_->bag.close();
}

namespace {
ros::Time Record(double stamp) { return ros::Time(stamp + kRecordOffset); }
}  // namespace

void TestBagWriter::Image(const std::string& topic, double stamp, uint32_t width, uint32_t height,
                          const std::string& encoding, int step, const std::vector<uint8_t>& data) {
  sensor_msgs::Image m;
  m.header.stamp = ros::Time(stamp);
  m.header.frame_id = "cam0";
  m.width = width;
  m.height = height;
  m.encoding = encoding;
  m.step = step;
  m.data = data;
  impl_->bag.write(topic, Record(stamp), m);
}

void TestBagWriter::CompressedImage(const std::string& topic, double stamp,
                                    const std::string& format, const std::vector<uint8_t>& data) {
  sensor_msgs::CompressedImage m;
  m.header.stamp = ros::Time(stamp);
  m.header.frame_id = "cam0";
  m.format = format;
  m.data = data;
  impl_->bag.write(topic, Record(stamp), m);
}

void TestBagWriter::CameraInfo(const std::string& topic, double stamp, int width, int height,
                               double fx, double fy, double cx, double cy) {
  sensor_msgs::CameraInfo m;
  m.header.stamp = ros::Time(stamp);
  m.header.frame_id = "cam0";
  m.width = width;
  m.height = height;
  m.distortion_model = "plumb_bob";
  m.D = {0, 0, 0, 0, 0};
  m.K = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
  m.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.P = {fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0};
  impl_->bag.write(topic, Record(stamp), m);
}

void TestBagWriter::Pose(const std::string& topic, const std::string& type, double stamp,
                         const double p[3], const double q[4]) {
  geometry_msgs::Pose pose;
  pose.position.x = p[0], pose.position.y = p[1], pose.position.z = p[2];
  pose.orientation.x = q[0], pose.orientation.y = q[1], pose.orientation.z = q[2];
  pose.orientation.w = q[3];
  if (type == "Odometry") {
    nav_msgs::Odometry m;
    m.header.stamp = ros::Time(stamp);
    m.header.frame_id = "world";
    m.child_frame_id = "cam0";
    m.pose.pose = pose;
    impl_->bag.write(topic, Record(stamp), m);
  } else {
    geometry_msgs::PoseStamped m;
    m.header.stamp = ros::Time(stamp);
    m.header.frame_id = "world";
    m.pose = pose;
    impl_->bag.write(topic, Record(stamp), m);
  }
}

}  // namespace sparseloop::test
