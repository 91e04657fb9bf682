// Issue #18's castle ring family: the Strecha castle-P30 ring (real images, exact poses) with raw
// poses made by drifting the GT relative motions (a heading bias per keyframe and / or a scale
// growth per keyframe, plus seeded random per-step noise). The pipeline must find the ring
// closure and the corrected trajectory must be much closer to the GT than the raw one: a verified
// loop pulls the drift back (docs/POSEGRAPH.md, "Loop information").
#include <cmath>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "real_data.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/pipeline/pipeline.h"
#include "test_util.h"

namespace sparseloop {
namespace {

struct Castle {
  Dataset dataset;
  Trajectory gt;
};

// The 30 views with their exact poses (tests/support/real_data.h reads the Strecha cameras).
Castle LoadCastleDataset() {
  Castle c;
  const auto root = test::DataDir() / "castle_p30_768";
  c.dataset.kind = "images";
  c.dataset.root = root / "images";
  c.gt.has_rotation = true;
  for (int i = 0; i < 30; ++i) {
    const test::Frame f = test::ReadStrechaCamera(
        root / "gt_dense_cameras" / fmt::format("{:04d}.jpg.camera", i), /*transpose=*/false);
    if (i == 0) c.dataset.intrinsics = f.intrinsics;
    DatasetFrame frame;
    frame.index = i;
    frame.timestamp = i;
    frame.image_path = root / "images" / fmt::format("{:04d}.jpg", i);
    c.dataset.frames.push_back(frame);
    StampedPose p;
    p.frame = i;
    p.timestamp = i;
    p.world_from_cam = f.world_from_cam;
    c.gt.poses.push_back(p);
  }
  return c;
}

struct DriftSpec {
  double yaw_deg = 0.0;     // heading bias per keyframe, about the camera's y axis (image down)
  double scale_step = 1.0;  // each raw step length is multiplied by scale_step^i
  uint64_t seed = 0;        // per-step noise: 0.1 deg rotation, 1 % translation (0 = none)
};

// Monocular drift of a raw vSLAM trajectory: every raw step is the GT step with the bias (and
// noise) applied, chained from the exact first pose.
Trajectory Drift(const Trajectory& gt, const DriftSpec& spec) {
  std::mt19937_64 rng(spec.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Eigen::Quaterniond yaw(
      Eigen::AngleAxisd(spec.yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()));
  Trajectory raw = gt;
  Rigid3d pose = gt.poses[0].world_from_cam;
  for (size_t i = 1; i < gt.poses.size(); ++i) {
    const Rigid3d& a = gt.poses[i - 1].world_from_cam;
    const Rigid3d& b = gt.poses[i].world_from_cam;
    Eigen::Quaterniond step_r = a.rotation.conjugate() * b.rotation * yaw;
    Eigen::Vector3d step_t = a.rotation.conjugate() * (b.translation - a.translation);
    step_t *= std::pow(spec.scale_step, static_cast<double>(i));
    if (spec.seed != 0) {
      const Eigen::Vector3d w(n01(rng), n01(rng), n01(rng));
      step_r = step_r *
               Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * M_PI / 180.0 * w.norm(), w.normalized()));
      step_t += 0.01 * step_t.norm() * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
    }
    pose = Rigid3d(pose.rotation * step_r, pose.translation + pose.rotation * step_t);
    pose.rotation.normalize();
    raw.poses[i].world_from_cam = pose;
  }
  return raw;
}

double Ate(const Trajectory& gt, const Trajectory& est) {
  EvaluationOptions options;
  options.compute_rpe = false;
  options.compute_kitti = false;
  return EvaluateTrajectory(gt, est, options).ate.rmse;
}

struct FamilyRow {
  DriftSpec spec;
  double raw_ate = 0.0;
  double corrected_ate = 0.0;
  int loops = 0;
  int accepted = 0;
};

FamilyRow RunFamilyRow(const Castle& castle, const DriftSpec& spec,
                       const PipelineOptions& options) {
  FamilyRow row;
  row.spec = spec;
  const Trajectory raw = Drift(castle.gt, spec);
  const PipelineResult result = RunPipeline(castle.dataset, raw, options);
  row.raw_ate = Ate(castle.gt, raw);
  row.corrected_ate = Ate(castle.gt, result.corrected);
  row.loops = static_cast<int>(result.loops.size());
  for (bool a : result.loop_accepted) row.accepted += a ? 1 : 0;
  return row;
}

std::vector<DriftSpec> FamilySpecs() {
  std::vector<DriftSpec> specs;
  // The five rows, then the same up to 1 deg and 1 % per keyframe with noise seeds.
  const std::vector<std::pair<double, double>> biases = {
      {0.2, 1.003}, {0.5, 1.005}, {1.0, 1.0}, {0.0, 1.01}, {1.0, 1.01}};
  for (const auto& [yaw, scale] : biases) specs.push_back({yaw, scale, 0});
  for (uint64_t seed : {11u, 12u}) {
    for (const auto& [yaw, scale] : biases) specs.push_back({yaw, scale, seed});
  }
  return specs;
}

TEST(CastleDriftFamily, CorrectedAteIsAtMost40PercentOfRaw) {
  SL_REQUIRE_DATA("castle_p30_768/images/0029.jpg");
  const Castle castle = LoadCastleDataset();
  const PipelineOptions options;
  for (const DriftSpec& spec : FamilySpecs()) {
    const FamilyRow row = RunFamilyRow(castle, spec, options);
    std::cerr << fmt::format(
        "castle drift {:.1f} deg, x{:.3f}, seed {}: raw ATE {:.3f}, corrected {:.3f} ({:.0f} %), "
        "loops {} accepted {}\n",
        spec.yaw_deg, spec.scale_step, spec.seed, row.raw_ate, row.corrected_ate,
        100.0 * row.corrected_ate / row.raw_ate, row.loops, row.accepted);
    EXPECT_GE(row.accepted, 1) << spec.yaw_deg << " " << spec.scale_step << " " << spec.seed;
    EXPECT_LE(row.corrected_ate, 0.4 * row.raw_ate)
        << spec.yaw_deg << " deg, x" << spec.scale_step << ", seed " << spec.seed;
  }
}

}  // namespace
}  // namespace sparseloop
