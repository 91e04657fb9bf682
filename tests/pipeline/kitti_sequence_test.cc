#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "sparseloop/io/dataset.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/kitti_sequence.h"
#include "sparseloop/synthetic/worlds.h"
#include "test_util.h"

namespace sparseloop::synthetic {
namespace {

// An aerial world of `textures` procedural textures of `size` pixels.
World SmallAerialWorld(int textures, int size) {
  ProceduralTextureOptions tex;
  tex.count = textures;
  tex.size = size;
  return MakeAerialWorld(MakeProceduralTextures(tex));
}

Trajectory Flight(int frames) {
  FlightPlanOptions plan;
  plan.frames = frames;
  return MakeFlightTrajectory(plan);
}

TEST(WriteKittiSequence, KittiLoaderReadsBackImagesPosesAndCalib) {
  const auto dir = test::TempDir() / "seq";
  const World world = SmallAerialWorld(3, 128);
  const Trajectory gt = Flight(12);
  CameraIntrinsics cam = DefaultAerialCamera();
  cam.width = 160, cam.height = 120, cam.cx = 79.5, cam.cy = 59.5, cam.fx = cam.fy = 125.0;
  SequenceOptions o;
  o.write_depth = true;
  o.num_threads = 2;
  int calls = 0;
  const auto r =
      WriteKittiSequence(dir, world, cam, gt, o, std::nullopt, [&](int64_t done, int64_t total) {
        ++calls;
        EXPECT_EQ(total, 12);
        EXPECT_LE(done, total);
      });
  EXPECT_EQ(r.frames, 12);
  EXPECT_EQ(calls, 12);

  const Dataset d = OpenDataset("kitti:" + dir.string());
  ASSERT_EQ(d.frames.size(), 12u);
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 125.0);
  EXPECT_DOUBLE_EQ(d.intrinsics.cy, 59.5);
  EXPECT_EQ(d.intrinsics.width, 160);
  ASSERT_TRUE(d.has_gt());
  for (size_t i = 0; i < 12; ++i) {
    ASSERT_TRUE(d.frames[i].gt_world_from_cam.has_value());
    EXPECT_LT((d.frames[i].gt_world_from_cam->translation - gt.poses[i].world_from_cam.translation)
                  .norm(),
              1e-6);
    EXPECT_NEAR(d.frames[i].timestamp, gt.poses[i].timestamp, 1e-6);
  }
  // The PNG holds exactly what the renderer produces for that frame.
  const auto frame5 = RenderFrame(world, cam, gt.poses[5].world_from_cam, o.render,
                                  PhotometricForFrame(5, o.photometric), 5);
  const cv::Mat png = cv::imread(d.frames[5].image_path.string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(png.type(), CV_8UC1);
  EXPECT_TRUE(std::equal(frame5.image.pixels.begin(), frame5.image.pixels.end(), png.data));
  const cv::Mat depth = cv::imread((dir / "depth_0" / "000005.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(depth.type(), CV_16UC1);
  EXPECT_NEAR(depth.at<uint16_t>(60, 80) / 256.0, frame5.depth.at(80, 60), 1.0 / 256);

  // Raw trajectory: same length, drifting, readable; mapped pixels present with raw depths.
  const Trajectory raw = ReadTrajectory(dir / "poses_raw.txt", TrajectoryFormat::kKitti);
  ASSERT_EQ(raw.size(), 12u);
  std::ifstream mapped(dir / "mapped" / "000005.txt");
  std::string header;
  std::getline(mapped, header);
  EXPECT_EQ(header, "# u v depth_raw");
  double u = 0, v = 0, z = 0;
  int count = 0;
  while (mapped >> u >> v >> z) {
    ++count;
    EXPECT_GT(z, 0.5 * FlightPlanOptions().altitude * 0.5);
  }
  EXPECT_GT(count, 10);
}

TEST(WriteKittiSequence, RejectsRawOfWrongLength) {
  const auto dir = test::TempDir();
  const World world = SmallAerialWorld(1, 32);
  const Trajectory gt = Flight(5);
  Trajectory raw = gt;
  raw.poses.pop_back();
  EXPECT_THROW(WriteKittiSequence(dir, world, DefaultAerialCamera(), gt, {}, raw),
               std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop::synthetic
