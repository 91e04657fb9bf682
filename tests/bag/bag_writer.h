#pragma once
// Writes ROS 1 bags for the tests with librosbag (bag_writer.cc is C++17, like every file that
// includes ROS headers; this header is std-only). Stamps in seconds; each message is recorded at
// its stamp + kRecordOffset (a bag refuses record time 0, and the rendered sequences start at 0).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace sparseloop::test {

inline constexpr double kRecordOffset = 1.0;  // seconds

class TestBagWriter {
 public:
  explicit TestBagWriter(const std::string& path);
  ~TestBagWriter();
  // sensor_msgs/Image (encoding mono8, bgr8, ...) with rows of `step` bytes (uint32 sizes, as in
  // the message).
  void Image(const std::string& topic, double stamp, uint32_t width, uint32_t height,
             const std::string& encoding, int step, const std::vector<uint8_t>& data);
  // sensor_msgs/CompressedImage (format "png", "jpeg").
  void CompressedImage(const std::string& topic, double stamp, const std::string& format,
                       const std::vector<uint8_t>& data);
  void CameraInfo(const std::string& topic, double stamp, int width, int height, double fx,
                  double fy, double cx, double cy);
  // type "PoseStamped" or "Odometry"; orientation x y z w.
  void Pose(const std::string& topic, const std::string& type, double stamp, const double p[3],
            const double q_xyzw[4]);
  void Close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sparseloop::test
