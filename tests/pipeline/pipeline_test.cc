#include "sparseloop/pipeline/pipeline.h"

#include "sparseloop/core/error.h"

#include <fstream>

#include <gtest/gtest.h>

#include "test_util.h"

namespace sparseloop {
namespace {

Dataset MakeDataset(const std::string& kind, int n) {
  Dataset d;
  d.kind = kind;
  for (int i = 0; i < n; ++i) {
    DatasetFrame f;
    f.index = i;
    f.timestamp = 100.0 + 0.1 * i;
    d.frames.push_back(f);
  }
  return d;
}

Trajectory MakeRaw(int n, bool timestamps, double t0 = 100.0, double dt = 0.1) {
  Trajectory t;
  t.has_timestamps = timestamps;
  for (int i = 0; i < n; ++i) {
    StampedPose p;
    p.frame = i;
    p.timestamp = timestamps ? t0 + dt * i : i;
    p.world_from_cam.translation = Eigen::Vector3d(i, 0, 0);
    t.poses.push_back(p);
  }
  return t;
}

TEST(MatchRawPoses, ByIndexForKitti) {
  const Dataset d = MakeDataset("kitti", 5);
  const Trajectory m = MatchRawPosesToFrames(d, MakeRaw(8, false), 0.02, "raw.txt");
  ASSERT_EQ(m.size(), 5u);
  EXPECT_EQ(m.poses[3].world_from_cam.translation.x(), 3.0);
  EXPECT_DOUBLE_EQ(m.poses[3].timestamp, 100.3);
}

TEST(MatchRawPoses, ShorterPoseFileIsAnErrorNamingTheFile) {
  const Dataset d = MakeDataset("kitti", 5);
  try {
    MatchRawPosesToFrames(d, MakeRaw(3, false), 0.02, "raw.txt");
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), "raw.txt");
    EXPECT_NE(std::string(e.what()).find("frame 3 has none"), std::string::npos) << e.what();
  }
}

TEST(MatchRawPoses, ByTimestampForTum) {
  const Dataset d = MakeDataset("tum", 5);
  // A 50 Hz raw trajectory, offset by 4 ms: each image takes the nearest raw pose.
  const Trajectory raw = MakeRaw(40, true, 100.004, 0.02);
  const Trajectory m = MatchRawPosesToFrames(d, raw, 0.02, "raw.txt");
  ASSERT_EQ(m.size(), 5u);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(m.poses[i].timestamp, 100.0 + 0.1 * i + 0.004, 1e-9);
  EXPECT_THROW(MatchRawPosesToFrames(d, MakeRaw(40, true, 200.0, 0.02), 0.02, "raw.txt"),
               FileError);
}

TEST(MappedPixels, ReadsAndRejectsMalformedLines) {
  const auto dir = test::TempDir();
  std::ofstream(dir / "ok.txt") << "# u v depth\n10.5 20 3.25\n11 21 -1\n";
  const MappedPixels m = ReadMappedPixels(dir / "ok.txt");
  ASSERT_EQ(m.pixels.size(), 2u);
  EXPECT_FLOAT_EQ(m.pixels[0].x, 10.5f);
  EXPECT_FLOAT_EQ(m.depths[1], -1.0f);
  std::ofstream(dir / "bad.txt") << "1 2 3\n4 5\n";
  try {
    ReadMappedPixels(dir / "bad.txt");
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 2);
  }
}

}  // namespace
}  // namespace sparseloop
