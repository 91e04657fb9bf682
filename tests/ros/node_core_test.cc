// NodeCore without ROS: the stamp synchronisation, the bounded queue, drops and parameter errors.
// (tests/ros/test_node.py runs the node itself against `sparseloop run`.)
#include "ros/node_core.h"

#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace sparseloop::ros_node {
namespace {

using bag_internal::CameraInfoMessage;
using bag_internal::ImageData;
using bag_internal::PoseMessage;

constexpr int kW = 320, kH = 240;

ImageData Image(double stamp, const std::string& encoding = "mono8") {
  cv::Mat img(kH, kW, CV_8UC1);
  cv::randu(img, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0);
  ImageData m;
  m.header.stamp = stamp;
  m.header.encoding = encoding;
  m.header.width = kW;
  m.header.height = kH;
  m.step = kW;
  m.data.assign(img.datastart, img.dataend);
  return m;
}

CameraInfoMessage Info() {
  CameraInfoMessage c;
  c.width = kW;
  c.height = kH;
  const double k[9] = {300, 0, 159.5, 0, 300, 119.5, 0, 0, 1};
  std::copy(k, k + 9, c.k);
  return c;
}

PoseMessage Pose(double stamp) {
  PoseMessage p;
  p.stamp = stamp;
  p.position[0] = stamp;  // moving along x
  return p;
}

// Polls until pred() or 30 s.
template <typename Pred>
bool WaitFor(Pred pred) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!pred()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

struct Warnings {
  std::mutex mutex;
  std::vector<std::string> lines;
  NodeCallbacks Callbacks() {
    NodeCallbacks c;
    c.on_warning = [this](const std::string& w) {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back(w);
    };
    return c;
  }
  bool Any(const std::string& needle) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& l : lines)
      if (l.find(needle) != std::string::npos) return true;
    return false;
  }
};

TEST(NodeCore, AnImageTakesThePoseNearestItsStampWithinMaxPoseDt) {
  NodeParams params;
  params.max_pose_dt = 0.01;
  NodeCore core(params, {});
  core.AddCameraInfo(Info());
  core.AddPose(Pose(0.995));  // 5 ms early: taken
  core.AddImage(Image(1.0));
  core.AddPose(Pose(2.02));  // 20 ms late: too far
  core.AddImage(Image(2.0));
  core.AddPose(Pose(3.0));  // lets the image at 2.0 go (no nearer pose can come)
  ASSERT_TRUE(WaitFor([&] { return core.Stats().keyframes == 2; }));
  const NodeStats s = core.Stats();
  EXPECT_EQ(s.keyframes_without_pose, 1);
  EXPECT_EQ(s.queued, 0);
  const auto summary = nlohmann::json::parse(core.Finish());
  EXPECT_EQ(summary["keyframes"], 2);
  EXPECT_EQ(summary["path_keyframes"], 1);  // only the one with a pose is in the graph
}

TEST(NodeCore, WithoutPosesTheQueueIsBoundedAndTheOldestGoesOnWithoutAPose) {
  NodeParams params;
  params.image_queue = 3;
  NodeCore core(params, {});
  core.AddCameraInfo(Info());
  for (int i = 0; i < 6; ++i) core.AddImage(Image(1.0 + i));
  // Six images, room for three: the three oldest went on although no pose came.
  ASSERT_TRUE(WaitFor([&] { return core.Stats().keyframes == 3; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(core.Stats().keyframes, 3);
  EXPECT_EQ(core.Stats().queued, 3);
  const auto summary = nlohmann::json::parse(core.Finish());  // the rest go at finish
  EXPECT_EQ(summary["keyframes"], 6);
  EXPECT_EQ(summary["keyframes_without_pose"], 6);
}

TEST(NodeCore, ImagesBeforeCameraInfoWaitAndAreDroppedWhenTheQueueIsFull) {
  Warnings warnings;
  NodeParams params;
  params.image_queue = 2;
  NodeCore core(params, warnings.Callbacks());
  for (int i = 0; i < 4; ++i) {
    core.AddPose(Pose(1.0 + i));
    core.AddImage(Image(1.0 + i));
  }
  ASSERT_TRUE(WaitFor([&] { return core.Stats().dropped_no_camera_info == 2; }));
  core.AddCameraInfo(Info());
  core.AddPose(Pose(10.0));
  ASSERT_TRUE(WaitFor([&] { return core.Stats().keyframes == 2; }));
  EXPECT_EQ(core.Stats().keyframes_without_pose, 0);
  EXPECT_TRUE(warnings.Any("no camera_info yet"));
}

TEST(NodeCore, LateDuplicateAndUndecodableImagesAreDroppedAndCounted) {
  Warnings warnings;
  NodeCore core(NodeParams{}, warnings.Callbacks());
  core.AddCameraInfo(Info());
  core.AddPose(Pose(1.0));
  core.AddPose(Pose(2.0));
  core.AddImage(Image(2.0));
  ASSERT_TRUE(WaitFor([&] { return core.Stats().keyframes == 1; }));
  core.AddImage(Image(1.0));  // before the one taken
  core.AddImage(Image(2.0));  // the same stamp again
  core.AddPose(Pose(3.0));
  core.AddImage(Image(3.0, "yuv422"));
  ImageData short_data = Image(3.5);
  short_data.data.resize(100);
  core.AddImage(short_data);
  const auto summary = nlohmann::json::parse(core.Finish());
  EXPECT_EQ(summary["keyframes"], 1);
  EXPECT_EQ(summary["dropped_out_of_order"], 2);
  EXPECT_EQ(summary["dropped_bad"], 2);
  EXPECT_TRUE(warnings.Any("'yuv422'"));
  EXPECT_TRUE(warnings.Any("100 bytes of data"));
}

// A 1x1 image aborted the node (OpenCV's assertion escaped the worker thread): it is dropped with
// the detector's reason, and the node goes on.
TEST(NodeCore, ATinyImageIsDroppedWithAWarning) {
  Warnings warnings;
  NodeCore core(NodeParams{}, warnings.Callbacks());
  CameraInfoMessage info;
  info.width = 1;
  info.height = 1;
  const double k[9] = {1, 0, 0.5, 0, 1, 0.5, 0, 0, 1};
  std::copy(k, k + 9, info.k);
  core.AddCameraInfo(info);
  ImageData tiny;
  tiny.header.stamp = 1.0;
  tiny.header.encoding = "mono8";
  tiny.header.width = 1;
  tiny.header.height = 1;
  tiny.step = 1;
  tiny.data = {0};
  core.AddImage(tiny);
  const auto summary = nlohmann::json::parse(core.Finish());
  EXPECT_EQ(summary["keyframes"], 0);
  EXPECT_EQ(summary["dropped_bad"], 1);
  EXPECT_TRUE(warnings.Any("image of 1x1 pixels is too small")) << warnings.lines.size();
}

TEST(NodeCore, BadPosesAndCameraInfoAreIgnoredWithAWarning) {
  Warnings warnings;
  NodeCore core(NodeParams{}, warnings.Callbacks());
  PoseMessage bad = Pose(1.0);
  bad.orientation_xyzw[3] = 2.0;  // not a unit quaternion
  core.AddPose(bad);
  CameraInfoMessage info = Info();
  info.k[0] = -1;  // negative focal length
  core.AddCameraInfo(info);
  EXPECT_TRUE(warnings.Any("unit quaternion"));
  EXPECT_TRUE(warnings.Any("camera_info ignored"));
  EXPECT_EQ(core.Stats().poses, 0);
  EXPECT_EQ(core.Stats().dropped_bad, 2);
}

// camera_info with fx = 1e308 was accepted, then every image was dropped with a packing error and
// the finish reported success: the message is refused with the reason, like a negative fx.
TEST(NodeCore, CameraInfoWithAnAbsurdFocalLengthIsRefusedWithTheReason) {
  Warnings warnings;
  NodeCore core(NodeParams{}, warnings.Callbacks());
  CameraInfoMessage info = Info();
  info.k[0] = 1e308;
  core.AddCameraInfo(info);
  EXPECT_TRUE(warnings.Any("fx must be at most"));
  EXPECT_EQ(core.Stats().dropped_bad, 1);
}

std::array<double, 36> Diagonal(const std::array<double, 6>& d) {
  std::array<double, 36> c{};
  for (int i = 0; i < 6; ++i) c[i * 6 + i] = d[i];
  return c;
}

// The step covariance is the growth of the absolute one, in the previous keyframe's axes.
TEST(StepCovarianceFromAbsolute, GrowthRotatedIntoThePreviousKeyframe) {
  const std::array<double, 36> prev = Diagonal({1, 1, 1, 0.01, 0.01, 0.01});
  const std::array<double, 36> now = Diagonal({5, 2, 10, 0.05, 0.02, 0.1});
  const std::array<double, 4> identity = {0, 0, 0, 1};
  auto step = StepCovarianceFromAbsolute(identity, prev, now);
  ASSERT_TRUE(step.has_value());
  const std::array<double, 36> growth = Diagonal({4, 1, 9, 0.04, 0.01, 0.09});
  for (int i = 0; i < 36; ++i) EXPECT_NEAR((*step)[i], growth[i], 1e-12) << i;
  // The previous camera turned 90 deg about z (its x axis is the world's y): world x's variance
  // is the camera's y, world y's the camera's x, for translation and rotation alike.
  const double h = std::sqrt(0.5);
  step = StepCovarianceFromAbsolute({0, 0, h, h}, prev, now);
  ASSERT_TRUE(step.has_value());
  const std::array<double, 36> turned = Diagonal({1, 4, 9, 0.01, 0.04, 0.09});
  for (int i = 0; i < 36; ++i) EXPECT_NEAR((*step)[i], turned[i], 1e-12) << i;
  // No growth in one direction, a shrink, or no covariance: not usable.
  EXPECT_FALSE(StepCovarianceFromAbsolute(identity, prev, prev).has_value());
  EXPECT_FALSE(StepCovarianceFromAbsolute(identity, now, prev).has_value());
  EXPECT_FALSE(StepCovarianceFromAbsolute(identity, std::array<double, 36>{}, now).has_value());
  EXPECT_FALSE(StepCovarianceFromAbsolute(identity, prev, Diagonal({5, 2, 10, 0.05, 0.02, 0.01}))
                   .has_value());
}

// PoseWithCovariance / Odometry messages: keyframes after the first take the growth between
// their poses' covariances as their odometry covariance; a covariance that does not grow falls
// back to the default model, with one warning.
TEST(NodeCore, PoseCovariancesGiveTheStepCovariance) {
  const auto run = [](bool growing, Warnings* warnings) {
    NodeCore core(NodeParams{}, warnings->Callbacks());
    core.AddCameraInfo(Info());
    for (int i = 0; i < 4; ++i) {
      PoseMessage p = Pose(1.0 + i);
      const double v = growing ? 0.01 * (i + 1) : 0.01;
      const std::array<double, 36> c = Diagonal({v, v, v, 0.1 * v, 0.1 * v, 0.1 * v});
      std::copy(c.begin(), c.end(), p.covariance);
      core.AddPose(p);
      core.AddImage(Image(1.0 + i));
    }
    return nlohmann::json::parse(core.Finish());
  };
  Warnings quiet;
  const auto growing = run(true, &quiet);
  EXPECT_EQ(growing["keyframes"], 4);
  EXPECT_EQ(growing["keyframes_with_covariance"], 3);
  EXPECT_EQ(growing["covariance_unusable"], 0);
  Warnings warned;
  const auto constant = run(false, &warned);
  EXPECT_EQ(constant["keyframes_with_covariance"], 0);
  EXPECT_EQ(constant["covariance_unusable"], 3);
  EXPECT_TRUE(warned.Any("default odometry model"));
}

TEST(NodeCore, BadParametersAndConfigKeysThrowNamingThem) {
  const auto message = [](const NodeParams& p) {
    try {
      NodeCore core(p, {});
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  NodeParams p;
  p.config_json = R"({"detector": {"nope": 1}})";
  EXPECT_NE(message(p).find("detector.nope"), std::string::npos) << message(p);
  p.config_json = "[1]";
  EXPECT_NE(message(p).find("~config must be a dictionary"), std::string::npos) << message(p);
  p.config_json = "{";
  EXPECT_NE(message(p).find("~config is not a JSON object"), std::string::npos) << message(p);
  // Nesting deeper than 64 levels is refused before parsing (200000 levels ran > 30 s), in ~config
  // and in ~config_file.
  p.config_json = std::string(100000, '[') + std::string(100000, ']');
  EXPECT_NE(message(p).find("~config: line 1: expected JSON nested at most 64 deep at column 65"),
            std::string::npos)
      << message(p);
  p.config_json.clear();
  {
    const auto deep = std::filesystem::temp_directory_path() / "sparseloop_node_core_deep.json";
    std::ofstream(deep) << std::string(100000, '{');
    p.config_file = deep.string();
    EXPECT_NE(message(p).find(deep.string() + ":1: expected JSON nested at most 64 deep"),
              std::string::npos)
        << message(p);
    p.config_file.clear();
  }
  p = NodeParams{};
  p.preset = "tiny";
  EXPECT_NE(message(p).find("~preset tiny: expected a preset name (dense | sparse)"),
            std::string::npos)
      << message(p);
  p.preset = "sparse";
  p.config_json = R"({"detector": {"check_every": 2}})";  // on top of the preset
  EXPECT_EQ(message(p), "no error");
  p = NodeParams{};
  p.max_pose_dt = 0;
  EXPECT_NE(message(p).find("~max_pose_dt"), std::string::npos);
  p = NodeParams{};
  p.image_queue = 0;
  EXPECT_NE(message(p).find("~image_queue"), std::string::npos);
  p = NodeParams{};
  p.config_file = "/nonexistent/config.json";
  EXPECT_NE(message(p).find("/nonexistent/config.json"), std::string::npos) << message(p);
  // Output files are checked at start, not at finish (a missing folder lost the session's
  // trajectory), and never one of the inputs or each other.
  p = NodeParams{};
  p.trajectory_file = "/nonexistent_dir/trajectory.txt";
  EXPECT_NE(message(p).find("~trajectory_file /nonexistent_dir/trajectory.txt"), std::string::npos)
      << message(p);
  const auto dir = std::filesystem::temp_directory_path() / "sparseloop_node_core_params";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "config.json") << "{}\n";
  p = NodeParams{};
  p.config_file = (dir / "config.json").string();
  p.loops_file = (dir / "sub" / ".." / "config.json").string();
  EXPECT_NE(message(p).find("got the file of ~config_file"), std::string::npos) << message(p);
  p = NodeParams{};
  p.trajectory_file = (dir / "out.txt").string();
  p.loops_file = (dir / "out.txt").string();
  EXPECT_NE(message(p).find("~loops_file"), std::string::npos) << message(p);
  p.loops_file = (dir / "loops.csv").string();
  EXPECT_EQ(message(p), "no error");
}

}  // namespace
}  // namespace sparseloop::ros_node
