// The rosbag: dataset kind against the folder it was written from: the CLI tests' rendered
// 60-frame circuit (tests/cli/cli_runner.h) recorded into ROS 1 bags by librosbag
// (bag_writer.cc), opened with OpenDatasetSpec, run through `sparseloop run` / `detect`, and
// broken in the ways a user's bag can be.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "bag/bag_writer.h"
#include "cli/cli_runner.h"
#include "real_data.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/dataset_source.h"
#include "test_util.h"

namespace sparseloop {
namespace {

namespace fs = std::filesystem;

const char* const kImage = "/cam0/image_raw";
const char* const kPose = "/vslam/pose";
const char* const kGt = "/ground_truth";

enum class Encoding { kMono8Padded, kRgb8, kPng };

struct Bags {
  fs::path
      mono;  // mono8 rows padded to width + 8, camera_info sibling, PoseStamped raw, Odometry gt
  fs::path rgb;  // rgb8 (gray replicated in 3 channels), no camera_info
  fs::path png;  // CompressedImage png, camera_info sibling, Odometry raw poses
};

void WritePose(test::TestBagWriter& bag, const std::string& topic, const std::string& type,
               double stamp, const Rigid3d& pose) {
  const double p[3] = {pose.translation.x(), pose.translation.y(), pose.translation.z()};
  const Eigen::Quaterniond& q = pose.rotation;
  const double xyzw[4] = {q.x(), q.y(), q.z(), q.w()};
  bag.Pose(topic, type, stamp, p, xyzw);
}

void WriteBag(const fs::path& path, const Dataset& seq, const Trajectory& raw, Encoding encoding) {
  test::TestBagWriter bag(path.string());
  const CameraIntrinsics& k = seq.intrinsics;
  for (size_t i = 0; i < seq.frames.size(); ++i) {
    const DatasetFrame& f = seq.frames[i];
    const cv::Mat gray = cv::imread(f.image_path.string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(gray.empty()) << f.image_path;
    if (encoding == Encoding::kMono8Padded) {
      const int step = gray.cols + 8;
      std::vector<uint8_t> data(static_cast<size_t>(step) * gray.rows, 0xEE);
      for (int r = 0; r < gray.rows; ++r) {
        std::copy(gray.ptr<uint8_t>(r), gray.ptr<uint8_t>(r) + gray.cols, &data[r * step]);
      }
      bag.Image(kImage, f.timestamp, gray.cols, gray.rows, "mono8", step, data);
    } else if (encoding == Encoding::kRgb8) {
      std::vector<uint8_t> data;
      data.reserve(gray.total() * 3);
      for (int r = 0; r < gray.rows; ++r) {
        for (int c = 0; c < gray.cols; ++c) data.insert(data.end(), 3, gray.at<uint8_t>(r, c));
      }
      bag.Image(kImage, f.timestamp, gray.cols, gray.rows, "rgb8", gray.cols * 3, data);
    } else {
      std::vector<uint8_t> png;
      ASSERT_TRUE(cv::imencode(".png", gray, png));
      bag.CompressedImage(std::string(kImage) + "/compressed", f.timestamp, "png", png);
    }
    if (i == 0 && encoding != Encoding::kRgb8) {
      bag.CameraInfo("/cam0/camera_info", f.timestamp, k.width, k.height, k.fx, k.fy, k.cx, k.cy);
    }
    WritePose(bag, kPose, encoding == Encoding::kPng ? "Odometry" : "PoseStamped", f.timestamp,
              raw.poses[i].world_from_cam);
    ASSERT_TRUE(f.gt_world_from_cam.has_value());
    WritePose(bag, kGt, "Odometry", f.timestamp, *f.gt_world_from_cam);
  }
  bag.Close();
}

struct Fixture {
  fs::path seq;
  Dataset folder;  // kitti:seq
  Trajectory raw;  // seq/poses_raw.txt
  Bags bags;
};

// The rendered sequence as a kitti: dataset and as three bags, written once per test binary.
const Fixture& TheFixture() {
  static const Fixture fixture = [] {
    Fixture f;
    f.seq = test::RenderedLoopSequence();
    f.folder = OpenDatasetSpec("kitti:" + f.seq.string());
    f.raw = ReadTrajectory(f.seq / "poses_raw.txt");
    const fs::path dir = test::TempDir("bags");
    f.bags = {dir / "mono.bag", dir / "rgb.bag", dir / "png.bag"};
    WriteBag(f.bags.mono, f.folder, f.raw, Encoding::kMono8Padded);
    WriteBag(f.bags.rgb, f.folder, f.raw, Encoding::kRgb8);
    WriteBag(f.bags.png, f.folder, f.raw, Encoding::kPng);
    return f;
  }();
  return fixture;
}

std::string Spec(const fs::path& bag, const std::string& query) {
  return "rosbag:" + bag.string() + "?" + query;
}

std::string MonoSpec() {
  return Spec(TheFixture().bags.mono, fmt::format("image={}&pose={}&gt={}", kImage, kPose, kGt));
}

TEST(RosbagDataset, FramesImagesIntrinsicsAndPosesAreTheFoldersOwn) {
  const Fixture& fx = TheFixture();
  ASSERT_EQ(fx.folder.frames.size(), 60u);
  ASSERT_EQ(fx.raw.size(), 60u);
  const std::map<std::string, std::string> specs = {
      {"mono8 padded", MonoSpec()},
      {"rgb8", Spec(fx.bags.rgb, fmt::format("image={}&pose={}&gt={}", kImage, kPose, kGt))},
      {"png", Spec(fx.bags.png,
                   fmt::format("image={}/compressed&camera_info=/cam0/camera_info&pose={}&gt={}",
                               kImage, kPose, kGt))}};
  for (const auto& [name, spec] : specs) {
    SCOPED_TRACE(name);
    DatasetOptions options;
    if (name == "rgb8") options.intrinsics = fx.folder.intrinsics;  // that bag has no camera_info
    const Dataset d = OpenDatasetSpec(spec, options);
    EXPECT_EQ(d.kind, "rosbag");
    ASSERT_EQ(d.frames.size(), fx.folder.frames.size());
    EXPECT_DOUBLE_EQ(d.intrinsics.fx, fx.folder.intrinsics.fx);
    EXPECT_DOUBLE_EQ(d.intrinsics.fy, fx.folder.intrinsics.fy);
    EXPECT_DOUBLE_EQ(d.intrinsics.cx, fx.folder.intrinsics.cx);
    EXPECT_DOUBLE_EQ(d.intrinsics.cy, fx.folder.intrinsics.cy);
    EXPECT_EQ(d.intrinsics.width, 640);
    EXPECT_EQ(d.intrinsics.height, 480);
    ASSERT_EQ(d.raw_poses.size(), fx.raw.size());
    for (size_t i = 0; i < d.frames.size(); ++i) {
      const DatasetFrame& bag_frame = d.frames[i];
      const DatasetFrame& file_frame = fx.folder.frames[i];
      EXPECT_EQ(bag_frame.index, file_frame.index);
      EXPECT_NEAR(bag_frame.timestamp, file_frame.timestamp, 1e-9);  // ros::Time holds ns
      ASSERT_TRUE(bag_frame.gt_world_from_cam.has_value()) << "frame " << i;
      EXPECT_LT(
          (bag_frame.gt_world_from_cam->translation - file_frame.gt_world_from_cam->translation)
              .norm(),
          1e-12);
      EXPECT_LT(bag_frame.gt_world_from_cam->rotation.angularDistance(
                    file_frame.gt_world_from_cam->rotation),
                1e-9);
      EXPECT_LT((d.raw_poses.poses[i].world_from_cam.translation -
                 fx.raw.poses[i].world_from_cam.translation)
                    .norm(),
                1e-12);
      EXPECT_NEAR(d.raw_poses.poses[i].timestamp, file_frame.timestamp, 1e-9);
    }
    // Images decode to the PNG's pixels (every 7th frame keeps the test quick).
    for (size_t i = 0; i < d.frames.size(); i += 7) {
      const cv::Mat from_bag = ReadFrameGray(d, d.frames[i]);
      const cv::Mat from_png = ReadFrameGray(fx.folder, fx.folder.frames[i]);
      ASSERT_EQ(from_bag.size(), from_png.size()) << "frame " << i;
      EXPECT_EQ(cv::norm(from_bag, from_png, cv::NORM_INF), 0.0) << "frame " << i;
    }
  }
}

// `run` on the bag (raw poses from its pose topic, no --poses) = `run` on the folder with
// --poses poses_raw.txt: the same loops, accepted loops, corrected trajectory and evaluation.
// The folder run ignores the render's mapped/ pixels (use_mapped_pixels false): the bag has none.
TEST(RosbagDataset, RunOnTheBagEqualsRunOnTheFolder) {
  const Fixture& fx = TheFixture();
  const fs::path out_bag = test::TempDir("run_bag") / "out";
  const fs::path out_dir = test::TempDir("run_dir") / "out";
  const fs::path no_mapped = test::TempDir("run_config") / "no_mapped.json";
  std::ofstream(no_mapped) << R"({"use_mapped_pixels": false})";
  const test::CliResult from_bag =
      test::RunCli({"run", "--dataset", MonoSpec(), "--out", out_bag.string()});
  ASSERT_EQ(from_bag.exit_code, 0) << from_bag.err;
  const test::CliResult from_dir =
      test::RunCli({"run", "--dataset", "kitti:" + fx.seq.string(), "--poses",
                    (fx.seq / "poses_raw.txt").string(), "--config", no_mapped.string(), "--out",
                    out_dir.string()});
  ASSERT_EQ(from_dir.exit_code, 0) << from_dir.err;

  const auto loops = [](const fs::path& dir) {
    std::vector<std::string> rows;
    std::ifstream in(dir / "loops.csv");
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
      // query,match,score,inliers,status,pose_kind,planar_alternative,accepted: the first 8.
      size_t cut = 0;
      for (int comma = 0; comma < 8 && cut != std::string::npos; ++comma) {
        cut = line.find(',', cut + (comma > 0));
      }
      rows.push_back(line.substr(0, cut));
    }
    return rows;
  };
  const std::vector<std::string> bag_loops = loops(out_bag);
  EXPECT_GE(bag_loops.size(), 10u);  // the second lap closes loops
  EXPECT_EQ(bag_loops, loops(out_dir));

  const Trajectory bag_traj = ReadTrajectory(out_bag / "trajectory.txt");
  const Trajectory dir_traj = ReadTrajectory(out_dir / "trajectory.txt");
  ASSERT_EQ(bag_traj.size(), dir_traj.size());
  double gap = 0.0;
  for (size_t i = 0; i < bag_traj.size(); ++i) {
    gap = std::max(gap, (bag_traj.poses[i].world_from_cam.translation -
                         dir_traj.poses[i].world_from_cam.translation)
                            .norm());
  }
  EXPECT_LT(gap, 1e-6) << "corrected trajectories differ";
  // The bag's gt topic is the evaluation's ground truth; the pose topic is named as the source.
  const nlohmann::json a = test::ReadJson(out_bag / "summary.json");
  const nlohmann::json b = test::ReadJson(out_dir / "summary.json");
  EXPECT_EQ(a.at("gt_file"), fx.bags.mono.string());
  EXPECT_EQ(a.at("poses_file"), fmt::format("{} topic {}", fx.bags.mono.string(), kPose));
  ASSERT_TRUE(a.contains("eval") && b.contains("eval")) << a.dump(2);
  EXPECT_EQ(a.at("loops_correct"), b.at("loops_correct"));
  EXPECT_EQ(a.at("accepted_loops_correct"), b.at("accepted_loops_correct"));
  for (const char* key : {"raw", "corrected"}) {
    for (const auto& [name, value] : b.at("eval").at(key).items()) {
      if (value.is_number_float()) {
        EXPECT_NEAR(a.at("eval").at(key).at(name).get<double>(), value.get<double>(),
                    1e-6 * (1.0 + std::abs(value.get<double>())))
            << key << "." << name;
      }
    }
  }
}

// `detect` takes the pose topic as --poses: the paper search area, not the global fallback. As in
// `run` (the same driver), the folder's mapped/ pixels are ignored: the bag has none.
TEST(RosbagDataset, DetectUsesThePoseTopic) {
  const Fixture& fx = TheFixture();
  const fs::path out_bag = test::TempDir("detect_bag") / "out";
  const fs::path out_dir = test::TempDir("detect_dir") / "out";
  const test::CliResult from_bag =
      test::RunCli({"detect", "--dataset", MonoSpec(), "--out", out_bag.string()});
  ASSERT_EQ(from_bag.exit_code, 0) << from_bag.err;
  const test::CliResult from_dir =
      test::RunCli({"detect", "--dataset", "kitti:" + fx.seq.string(), "--poses",
                    (fx.seq / "poses_raw.txt").string(), "--set", "use_mapped_pixels=false",
                    "--out", out_dir.string()});
  ASSERT_EQ(from_dir.exit_code, 0) << from_dir.err;
  const nlohmann::json a = test::ReadJson(out_bag / "summary.json");
  const nlohmann::json b = test::ReadJson(out_dir / "summary.json");
  EXPECT_EQ(a.at("status_counts"), b.at("status_counts"));
  EXPECT_GT(a.at("status_counts").at("detected").get<int>(), 0);
}

// The real castle-P30 ring recorded as a bag the way a camera driver would (the JPEG files as
// sensor_msgs/CompressedImage, camera_info, the exact poses on the pose and gt topics): `run` on
// it closes the ring (views 0027-0029 back to 0000-0003).
TEST(RosbagDataset, CastleBagFindsItsLoop) {
  SL_REQUIRE_DATA("castle_p30_768/images/0029.jpg");
  const fs::path root = test::DataDir() / "castle_p30_768";
  const fs::path bag_path = test::TempDir("castle") / "castle.bag";
  {
    test::TestBagWriter bag(bag_path.string());
    for (int i = 0; i < 30; ++i) {
      const std::string name = fmt::format("{:04d}.jpg", i);
      const test::Frame f =
          test::ReadStrechaCamera(root / "gt_dense_cameras" / (name + ".camera"), false);
      std::ifstream in(root / "images" / name, std::ios::binary);
      const std::vector<uint8_t> jpeg((std::istreambuf_iterator<char>(in)), {});
      ASSERT_GT(jpeg.size(), 1000u) << name;
      const double stamp = 10.0 + i;
      bag.CompressedImage("/castle/image/compressed", stamp, "jpeg", jpeg);
      if (i == 0) {
        const CameraIntrinsics& k = f.intrinsics;
        bag.CameraInfo("/castle/camera_info", stamp, k.width, k.height, k.fx, k.fy, k.cx, k.cy);
      }
      WritePose(bag, "/castle/pose", "PoseStamped", stamp, f.world_from_cam);
      WritePose(bag, kGt, "Odometry", stamp, f.world_from_cam);
    }
    bag.Close();
  }
  const std::string spec = Spec(bag_path, fmt::format("image=/castle/image/compressed&camera_info="
                                                      "/castle/camera_info&pose=/castle/pose&gt={}",
                                                      kGt));
  const Dataset d = OpenDatasetSpec(spec);
  ASSERT_EQ(d.frames.size(), 30u);
  EXPECT_EQ(d.intrinsics.width, 768);
  EXPECT_EQ(d.intrinsics.height, 512);
  const fs::path out = test::TempDir("castle_run") / "out";
  const test::CliResult run = test::RunCli({"run", "--dataset", spec, "--out", out.string()});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::ifstream loops(out / "loops.csv");
  std::string line;
  std::getline(loops, line);
  int ring_closures = 0;
  while (std::getline(loops, line)) {
    int query = -1, match = -1;
    ASSERT_EQ(std::sscanf(line.c_str(), "%d,%d", &query, &match), 2) << line;
    ring_closures += (query >= 27 && match <= 3) ? 1 : 0;
  }
  EXPECT_GE(ring_closures, 1) << "no ring closure in " << (out / "loops.csv");
  const nlohmann::json summary = test::ReadJson(out / "summary.json");
  EXPECT_GE(summary.at("accepted_loops").get<int>(), 1) << summary.dump(2);
  EXPECT_EQ(summary.at("accepted_loops_false").get<int>(), 0) << summary.dump(2);
}

// What a user's bag gets wrong: each is an error naming the bag (or the spec) and saying what it
// expected, never a crash.
TEST(RosbagDataset, BadBagsAndSpecsAreClearErrors) {
  const Fixture& fx = TheFixture();
  const auto expect_file_error = [](const std::string& spec, const std::string& file,
                                    const std::string& text) {
    try {
      OpenDatasetSpec(spec);
      ADD_FAILURE() << "no error for " << spec;
    } catch (const FileError& e) {
      EXPECT_EQ(e.file(), file) << e.what();
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  const std::string mono = fx.bags.mono.string();
  // A topic the bag does not have: the message lists those it has.
  expect_file_error(Spec(fx.bags.mono, "image=/cam1/image_raw"), mono,
                    "/cam0/image_raw (sensor_msgs/Image)");
  expect_file_error(Spec(fx.bags.mono, fmt::format("image={}&pose=/odom", kImage)), mono,
                    "no such topic");
  // A missing file.
  expect_file_error(Spec(fx.bags.mono.parent_path() / "missing.bag", "image=/a"),
                    (fx.bags.mono.parent_path() / "missing.bag").string(), "missing");
  // A bag cut short (the recorder was killed): no index.
  const fs::path cut = test::TempDir("cut") / "cut.bag";
  {
    std::ifstream in(fx.bags.mono, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream out(cut, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  }
  expect_file_error(Spec(cut, fmt::format("image={}", kImage)), cut.string(), "cut short");
  // Not a bag at all.
  const fs::path text = test::TempDir("text") / "notes.bag";
  std::ofstream(text) << "not a bag\n";
  expect_file_error(Spec(text, fmt::format("image={}", kImage)), text.string(),
                    "a readable ROS bag");
  // An image topic of the wrong type.
  expect_file_error(Spec(fx.bags.mono, fmt::format("image={}", kPose)), mono,
                    "on topic /vslam/pose (message 0), got geometry_msgs/PoseStamped");
  // An unsupported encoding, reported when the frame is read, naming the message.
  const fs::path yuv = test::TempDir("yuv") / "yuv.bag";
  {
    test::TestBagWriter bag(yuv.string());
    bag.Image(kImage, 0.5, 32, 32, "yuv422", 64, std::vector<uint8_t>(64 * 32, 0));
    bag.Close();
  }
  DatasetOptions options;
  options.intrinsics = CameraIntrinsics{};
  options.intrinsics->fx = options.intrinsics->fy = 30;
  options.intrinsics->cx = options.intrinsics->cy = 16;
  const Dataset d = OpenDatasetSpec(Spec(yuv, fmt::format("image={}", kImage)), options);
  try {
    ReadFrameGray(d, d.frames[0]);
    ADD_FAILURE() << "yuv422 decoded";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), yuv.string());
    EXPECT_NE(std::string(e.what()).find("'yuv422'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("message 0 of topic /cam0/image_raw"), std::string::npos)
        << e.what();
  }
  // A width beyond int (uint32 in the message) is refused as given: it was printed as -294967296.
  const fs::path wide = test::TempDir("wide") / "wide.bag";
  {
    test::TestBagWriter bag(wide.string());
    bag.Image(kImage, 0.5, 4000000000u, 32, "mono8", 64, std::vector<uint8_t>(64 * 32, 0));
    bag.Close();
  }
  expect_file_error(Spec(wide, fmt::format("image={}", kImage)), wide.string(),
                    "got 4000000000x32");
  // Spec errors: unknown key, no image topic, a topic without '/'; no intrinsics anywhere.
  EXPECT_THROW(OpenDatasetSpec(Spec(fx.bags.mono, "image=/cam0/image_raw&imu=/imu")),
               std::invalid_argument);
  EXPECT_THROW(OpenDatasetSpec("rosbag:" + mono), std::invalid_argument);
  EXPECT_THROW(OpenDatasetSpec(Spec(fx.bags.mono, "image=cam0")), std::invalid_argument);
  EXPECT_THROW(OpenDatasetSpec(Spec(fx.bags.rgb, fmt::format("image={}", kImage))),
               std::invalid_argument);
}

// The CLI: an error names the bag and exits 2; `run` on a bag without a pose topic and without
// --poses says what it needs.
TEST(RosbagDataset, CliErrorsNameTheBag) {
  const Fixture& fx = TheFixture();
  const test::CliResult missing_topic =
      test::RunCli({"detect", "--dataset", Spec(fx.bags.mono, "image=/nope"), "--out",
                    (test::TempDir("cli_err") / "out").string()});
  EXPECT_EQ(missing_topic.exit_code, 2);
  EXPECT_NE(missing_topic.err.find(fx.bags.mono.string()), std::string::npos) << missing_topic.err;
  EXPECT_NE(missing_topic.err.find("/nope"), std::string::npos) << missing_topic.err;
  const test::CliResult no_poses =
      test::RunCli({"run", "--dataset", Spec(fx.bags.mono, fmt::format("image={}", kImage)),
                    "--out", (test::TempDir("cli_err2") / "out").string()});
  EXPECT_EQ(no_poses.exit_code, 2);
  EXPECT_NE(no_poses.err.find("--poses is required"), std::string::npos) << no_poses.err;
}

}  // namespace
}  // namespace sparseloop
