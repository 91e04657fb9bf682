#include <algorithm>
#include <cmath>
#include <fstream>

#include <gtest/gtest.h>

#include "sparseloop/io/loop_pairs.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/synthetic/renderer.h"
#include "sparseloop/synthetic/worlds.h"
#include "test_util.h"

namespace sparseloop::synthetic {
namespace {

TEST(FlightPlan, CircuitRevisitsEveryPlaceOncePerLap) {
  FlightPlanOptions o;
  o.plan = FlightPlan::kCircuit;
  o.laps = 2;
  o.frames = 2001;  // frame i and i + 1000 are the same place
  const Trajectory t = MakeFlightTrajectory(o);
  ASSERT_EQ(t.size(), 2001u);
  for (int i = 0; i < 1000; i += 50) {
    const auto& a = t.poses[i].world_from_cam;
    const auto& b = t.poses[i + 1000].world_from_cam;
    EXPECT_LT((a.translation - b.translation).norm(), 0.5) << i;
    EXPECT_LT(RotationAngle(a.rotation, b.rotation), 0.05) << i;
    EXPECT_NEAR(a.translation.z(), o.altitude, 1e-9);
    // Nadir camera: optical axis straight down.
    EXPECT_LT((a.rotation * Eigen::Vector3d::UnitZ() + Eigen::Vector3d::UnitZ()).norm(), 1e-9);
  }
  EXPECT_DOUBLE_EQ(t.poses[10].timestamp, 1.0);
}

// Every plan must revisit: some pair of frames far apart in time is within a few metres.
TEST(FlightPlan, EveryPlanRevisitsPlaces) {
  for (FlightPlan plan : {FlightPlan::kCircuit, FlightPlan::kFigure8, FlightPlan::kLawnmower}) {
    FlightPlanOptions o;
    o.plan = plan;
    o.frames = 600;
    const auto p = MakeFlightTrajectory(o).Positions();
    int revisits = 0;
    for (size_t i = 0; i < p.size(); ++i)
      for (size_t j = 0; j + 100 < i; ++j)
        if ((p[i] - p[j]).norm() < 3.0) ++revisits;
    EXPECT_GT(revisits, 3) << ToString(plan);
    EXPECT_EQ(ParseFlightPlan(ToString(plan)), plan);
  }
  EXPECT_THROW(ParseFlightPlan("spiral"), std::invalid_argument);
}

TEST(FlightPlan, TiltLooksForward) {
  FlightPlanOptions o;
  o.tilt_deg = 30.0;
  o.frames = 100;
  const auto t = MakeFlightTrajectory(o);
  const auto& pose = t.poses[5].world_from_cam;
  const Eigen::Vector3d axis = pose.rotation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d motion = t.poses[6].world_from_cam.translation - pose.translation;
  EXPECT_NEAR(std::acos(-axis.z()) * 180.0 / M_PI, 30.0, 1e-6);
  EXPECT_GT(axis.dot(motion), 0.0);
}

TEST(KittiIntrinsics, KnownValues) {
  EXPECT_DOUBLE_EQ(KittiCam0Intrinsics(0).fx, 718.856);
  EXPECT_EQ(KittiCam0Intrinsics(2).width, 1241);
  EXPECT_DOUBLE_EQ(KittiCam0Intrinsics(3).cy, 172.854);
  EXPECT_EQ(KittiCam0Intrinsics(7).height, 370);
  EXPECT_THROW(KittiCam0Intrinsics(13), std::invalid_argument);
}

// Downsampled, normalised cross-correlation: a crude place-similarity measure.
double DownsampledNcc(const Image8& a, const Image8& b, int factor) {
  const int w = a.width / factor, h = a.height / factor;
  std::vector<double> x, y;
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double sa = 0, sb = 0;
      for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i) {
          sa += a.at(u * factor + i, v * factor + j);
          sb += b.at(u * factor + i, v * factor + j);
        }
      x.push_back(sa), y.push_back(sb);
    }
  double mx = 0, my = 0;
  for (size_t i = 0; i < x.size(); ++i) mx += x[i], my += y[i];
  mx /= x.size(), my /= y.size();
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxy / std::sqrt(sxx * syy + 1e-12);
}

class StreetWorld00 : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto path = test::DataDir() / "kitti_gt_poses" / "00.txt";
    if (!std::filesystem::exists(path)) return;
    gt_ = new Trajectory(ReadTrajectory(path, TrajectoryFormat::kKitti));
    world_ = new World(MakeStreetWorld(*gt_, MakeProceduralTextures()));
  }
  static void TearDownTestSuite() {
    delete gt_;
    delete world_;
    gt_ = nullptr;
    world_ = nullptr;
  }
  static Trajectory* gt_;
  static World* world_;
};
Trajectory* StreetWorld00::gt_ = nullptr;
World* StreetWorld00::world_ = nullptr;

// Oracle: no facade may come within the road clearance of any pose (brute force over all poses).
TEST_F(StreetWorld00, NoFacadeBlocksTheRoad) {
  SL_REQUIRE_DATA("kitti_gt_poses/00.txt");
  const StreetWorldOptions o;
  const auto positions = gt_->Positions();
  int facades = 0;
  for (const Quad& q : world_->quads) {
    if (q.infinite || std::abs(q.axis_v.dot(o.down)) < 0.5) continue;  // ground
    ++facades;
    // Camera-height line of the facade.
    const Eigen::Vector3d top = q.origin;
    for (const auto& p : positions) {
      const double a = std::clamp((p - top).dot(q.axis_u), 0.0, q.size_u);
      const double b = std::clamp((p - top).dot(q.axis_v), 0.0, q.size_v);
      const double dist = (p - (top + a * q.axis_u + b * q.axis_v)).norm();
      ASSERT_GT(dist, o.road_clearance - 0.5);
    }
  }
  EXPECT_GT(facades, 300);
}

// Every GT pose sees facades and ground, and the depth is valid below the horizon.
TEST_F(StreetWorld00, RendersAnyFrameAtKittiResolution) {
  SL_REQUIRE_DATA("kitti_gt_poses/00.txt");
  const CameraIntrinsics cam = KittiCam0Intrinsics(0);
  RenderOptions o;
  o.num_threads = 2;
  for (size_t i : {size_t{0}, size_t{1000}, size_t{4540}}) {
    const auto f = RenderFrame(*world_, cam, gt_->poses[i].world_from_cam, o);
    ASSERT_EQ(f.image.width, 1241);
    ASSERT_EQ(f.image.height, 376);
    int valid_bottom = 0;
    for (int u = 0; u < cam.width; ++u) valid_bottom += f.depth.at(u, cam.height - 1) > 0.0f;
    EXPECT_EQ(valid_bottom, cam.width) << "frame " << i << ": the road is missing";
    // The road right below the camera is camera_height down: bottom-centre depth ~ h*fy/(v-cy).
    const double expected = 1.65 * cam.fy / (cam.height - 1 - cam.cy);
    EXPECT_NEAR(f.depth.at(cam.width / 2, cam.height - 1), expected, 0.25 * expected) << i;
  }
}

// Known revisits (published loop GT) look alike; different places do not.
TEST_F(StreetWorld00, RevisitsLookAlikeDifferentPlacesDoNot) {
  SL_REQUIRE_DATA("kitti_gt_poses/00.txt");
  SL_REQUIRE_DATA("kitti_loop_gt/z014xw_kitti00GroundTruth.txt");
  const auto pairs =
      ReadLoopPairs(test::DataDir() / "kitti_loop_gt" / "z014xw_kitti00GroundTruth.txt");
  // One pair from each revisited stretch: the closest in GT position among pairs with that query
  // hundred.
  std::vector<LoopPair> chosen;
  for (int64_t q0 : {1570, 2450, 3300, 3450, 3750, 4480}) {
    double best = 1e9;
    LoopPair pick{-1, -1};
    for (const auto& p : pairs) {
      if (p.query < q0 || p.query >= q0 + 30) continue;
      const double d = (gt_->poses[p.query].world_from_cam.translation -
                        gt_->poses[p.match].world_from_cam.translation)
                           .norm();
      if (d < best) best = d, pick = p;
    }
    if (pick.query >= 0) chosen.push_back(pick);
  }
  ASSERT_GE(chosen.size(), 5u);
  const CameraIntrinsics cam = KittiCam0Intrinsics(0);
  RenderOptions o;
  o.num_threads = 2;
  auto render = [&](int64_t i) {
    return RenderFrame(*world_, cam, gt_->poses[i].world_from_cam, o, {}, i).image;
  };
  int wins = 0;
  for (const auto& p : chosen) {
    const Image8 q = render(p.query), m = render(p.match);
    // A frame from elsewhere: > 100 m from the query in GT.
    const int64_t n = static_cast<int64_t>(gt_->size());
    int64_t other = (p.query + 500) % n;
    while ((gt_->poses[other].world_from_cam.translation -
            gt_->poses[p.query].world_from_cam.translation)
               .norm() < 100.0) {
      other = (other + 97) % n;
    }
    const Image8 x = render(other);
    const double same = DownsampledNcc(q, m, 16);
    const double diff = DownsampledNcc(q, x, 16);
    RecordProperty("pair_" + std::to_string(p.query),
                   std::to_string(same) + " vs " + std::to_string(diff));
    EXPECT_GT(same, 0.3) << p.query << "-" << p.match;
    wins += same > diff + 0.15;
  }
  EXPECT_GE(wins, static_cast<int>(chosen.size()) - 1);
}

}  // namespace
}  // namespace sparseloop::synthetic

namespace sparseloop::synthetic {
namespace {

// The mosaic is continuous across tile borders (cross-fade) and tiles differ from each other.
TEST(AerialMosaic, ContinuousAtBordersAndNonRepeating) {
  ProceduralTextureOptions tex;
  tex.count = 4;
  tex.size = 256;
  AerialWorldOptions o;
  const World world = MakeAerialWorld(MakeProceduralTextures(tex), o);
  const double footprint = 0.05;  // metres per pixel
  double max_jump = 0.0;
  for (int k = -5; k <= 5; ++k) {
    for (double t = 1.0; t < o.tile_size; t += 2.3) {
      const double border = k * o.tile_size;
      const float a = world.Shade(0, {border - 1e-7, t}, footprint);
      const float b = world.Shade(0, {border + 1e-7, t}, footprint);
      max_jump = std::max(max_jump, static_cast<double>(std::abs(a - b)));
    }
  }
  EXPECT_LT(max_jump, 0.5) << "visible seam at a tile border";
  // Tile interiors: 8x8 patches at the same in-tile position of 30 tiles are pairwise different.
  std::vector<std::vector<float>> patches;
  for (int i = 0; i < 30; ++i) {
    std::vector<float> p;
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        p.push_back(world.Shade(
            0,
            {(i * 7 % 13) * o.tile_size + 10.0 + 0.3 * x, (i / 13) * o.tile_size + 10.0 + 0.3 * y},
            footprint));
    patches.push_back(p);
  }
  for (size_t i = 0; i < patches.size(); ++i)
    for (size_t j = 0; j < i; ++j) {
      double diff = 0.0;
      for (size_t k = 0; k < patches[i].size(); ++k)
        diff += std::abs(patches[i][k] - patches[j][k]);
      EXPECT_GT(diff / patches[i].size(), 1.0) << "tiles " << i << " and " << j << " repeat";
    }
}

}  // namespace
}  // namespace sparseloop::synthetic
