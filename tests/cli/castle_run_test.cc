// End to end on real images: `sparseloop run` on Strecha castle-P30 (one ring around a
// courtyard, 30 views with exact GT poses) with a drifted copy of the GT as the raw vSLAM poses.
// The detector must find the ring closure 0029 -> 0001 (or 0002) with the drifted poses, and the
// pose graph must lower the ATE against GT.
#include <cmath>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "sparseloop/core/sim3.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

// Strecha .camera: K (3x3), 3 zeros, R (3x3), camera centre (3), width height;
// world_from_cam = [R | c] (tests/support/real_data.h checks this against the images).
Rigid3d ReadCastlePose(const std::filesystem::path& file, double k[4]) {
  std::ifstream in(file);
  double v[26];
  for (double& x : v) in >> x;
  EXPECT_TRUE(in.good()) << file;
  k[0] = v[0];
  k[1] = v[4];
  k[2] = v[2];
  k[3] = v[5];
  Eigen::Matrix3d r;
  r << v[12], v[13], v[14], v[15], v[16], v[17], v[18], v[19], v[20];
  return Rigid3d(Eigen::Quaterniond(r), Eigen::Vector3d(v[21], v[22], v[23]));
}

void WriteKitti(const std::filesystem::path& path, const std::vector<Sim3d>& poses) {
  std::ofstream out(path);
  for (const Sim3d& p : poses) {
    const Eigen::Matrix3d r = p.rotation.toRotationMatrix();
    for (int row = 0; row < 3; ++row) {
      out << fmt::format("{:.12g} {:.12g} {:.12g} {:.12g}", r(row, 0), r(row, 1), r(row, 2),
                         p.translation[row]);
      out << (row < 2 ? " " : "\n");
    }
  }
}

// Monocular drift: each raw step is the GT step with an extra rotation of `yaw_deg` about the
// camera's y axis (image down: heading drift) and its length multiplied by exp(i * log_scale),
// i.e. the accumulated yaw and scale drift of a monocular VO. Frame 0 is exact.
std::vector<Sim3d> Drift(const std::vector<Sim3d>& gt, double yaw_deg, double log_scale) {
  std::vector<Sim3d> raw = {gt[0]};
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()));
  for (size_t i = 1; i < gt.size(); ++i) {
    Sim3d step = gt[i - 1].Inverse() * gt[i];
    step.rotation = step.rotation * yaw;
    step.translation *= std::exp(static_cast<double>(i) * log_scale);
    Sim3d next = raw.back() * step;
    next.scale = 1.0;
    raw.push_back(next);
  }
  return raw;
}

// `sparseloop run` on the castle images with `raw` as the raw poses; summary.json and loops.csv.
struct CastleRun {
  nlohmann::json summary;
  std::string loops_csv;
};
CastleRun RunCastle(const std::filesystem::path& root, const double k[4],
                    const std::vector<Sim3d>& gt, const std::vector<Sim3d>& raw,
                    const std::string& name, const std::vector<std::string>& extra = {}) {
  auto fixtures = TempDir();
  fixtures += "_" + name;
  std::filesystem::remove_all(fixtures);
  std::filesystem::create_directories(fixtures);
  WriteKitti(fixtures / "gt.txt", gt);
  WriteKitti(fixtures / "raw.txt", raw);
  const auto out = fixtures / "out";
  std::vector<std::string> args = {"run",
                                   "--dataset",
                                   "images:" + (root / "images").string(),
                                   "--intrinsics",
                                   fmt::format("{},{},{},{}", k[0], k[1], k[2], k[3]),
                                   "--poses",
                                   (fixtures / "raw.txt").string(),
                                   "--gt",
                                   (fixtures / "gt.txt").string(),
                                   "--out",
                                   out.string(),
                                   "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  const CliResult r = RunCli(args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  CastleRun run;
  std::ifstream in(out / "summary.json");
  run.summary = nlohmann::json::parse(in);
  std::ifstream loops_in(out / "loops.csv");
  run.loops_csv.assign(std::istreambuf_iterator<char>(loops_in), {});
  return run;
}

std::vector<Sim3d> LoadCastleGt(const std::filesystem::path& root, double k[4]) {
  std::vector<Sim3d> gt;
  for (int i = 0; i < 30; ++i) {
    gt.push_back(
        Sim3d(ReadCastlePose(root / "gt_dense_cameras" / fmt::format("{:04d}.jpg.camera", i), k)));
  }
  return gt;
}

bool HasRingClosure(const std::string& loops_csv) {
  return loops_csv.find("\n29,1,") != std::string::npos ||
         loops_csv.find("\n29,2,") != std::string::npos;
}

TEST(CliRunCastle, DriftedRingIsClosedAndAteDrops) {
  SL_REQUIRE_DATA("castle_p30_768/images/0029.jpg");
  const auto root = DataDir() / "castle_p30_768";
  double k[4] = {0, 0, 0, 0};
  const std::vector<Sim3d> gt = LoadCastleGt(root, k);
  // 0.3 deg yaw and 0.5 % scale per step (8.7 deg and 15 % at the end of the ring), and 1 deg /
  // 1 % per step (29 deg, 34 %; formerly documented as a known gap: no loop at all).
  struct DriftLevel {
    double yaw_deg, log_scale;
    const char* name;
  };
  for (const DriftLevel& d :
       {DriftLevel{0.3, 0.005, "drift03"}, DriftLevel{1.0, 0.01, "drift10"}}) {
    SCOPED_TRACE(d.name);
    const CastleRun run = RunCastle(root, k, gt, Drift(gt, d.yaw_deg, d.log_scale), d.name);
    const nlohmann::json& summary = run.summary;
    const std::string& loops_csv = run.loops_csv;
    const double raw_ate = summary["eval"]["raw"]["ate_rmse_m"].get<double>();
    const double corrected_ate = summary["eval"]["corrected"]["ate_rmse_m"].get<double>();
    std::cerr << fmt::format("castle {}: raw ATE {:.3f} m, corrected {:.3f} m ({:.0f}%)\n", d.name,
                             raw_ate, corrected_ate, 100 * corrected_ate / raw_ate)
              << loops_csv;
    EXPECT_TRUE(HasRingClosure(loops_csv))
        << "the ring closure 0029 -> 0001/0002 was not detected:\n"
        << loops_csv;
    EXPECT_GE(summary["accepted_loops"].get<int>(), 1);
    // 30 keyframes, a loop from 29: the chain reduction leaves the loop ends, the gauge and every
    // 8th chain vertex in the solve.
    const nlohmann::json& optimizer = summary["optimizer"];
    EXPECT_EQ(optimizer["vertices"].get<int>(), 30);
    EXPECT_LT(optimizer["solved_vertices"].get<int>(), 30);
    EXPECT_GE(optimizer["solved_vertices"].get<int>(), 3);
    EXPECT_LT(optimizer["final_cost"].get<double>(), optimizer["initial_cost"].get<double>());
    EXPECT_EQ(loops_csv.substr(0, loops_csv.find('\n')),
              "query,match,score,inliers,status,pose_kind,planar_alternative,accepted,correct,qx,"
              "qy,qz,qw,tx,ty,tz,scale,match_session,query_image,match_image,method,"
              "local_poses_from_images,local_poses_raw");
    // Reached: 1.107 -> 0.247 m (22 %) and 2.967 -> 0.531 m (18 %), one metric loop 29 -> 02
    // (local-map PnP) each; an earlier version reached 89 % at the smaller drift (its odometry
    // model was stiffer than this drift, before the loop weight rounds).
    EXPECT_LT(corrected_ate, 0.4 * raw_ate);
  }
}

}  // namespace
}  // namespace sparseloop::test
