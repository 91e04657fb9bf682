// Standard pose-graph benchmarks from ../shared/data/pose_graphs.
#include <fstream>
#include <sstream>

#include "sparseloop/core/error.h"
#include "sparseloop/eval/align.h"
#include "sparseloop/posegraph/g2o.h"
#include "test_util.h"

namespace sparseloop {
namespace {

std::filesystem::path Graphs() { return test::DataDir() / "pose_graphs"; }

PoseGraphOptions PlainOptions() {
  PoseGraphOptions options;
  options.rejection = OutlierRejection::kNone;
  options.loop_loss = RobustLoss::kTrivial;
  options.max_iterations = 100;
  return options;
}

TEST(G2oData, ParkingGarageConverges) {
  SL_REQUIRE_DATA("pose_graphs/parking-garage.g2o");
  PoseGraph graph = ReadG2o(Graphs() / "parking-garage.g2o");
  EXPECT_EQ(graph.num_vertices(), 1661u);
  EXPECT_EQ(graph.edges().size(), 6275u);
  EXPECT_EQ(graph.vertex_type(), VertexType::kSe3);
  const PoseGraphSummary s = graph.Optimize(PlainOptions());
  std::cerr << s.BriefReport() << "\n";
  EXPECT_EQ(s.status, PoseGraphStatus::kConverged);
  EXPECT_LT(s.final_cost, s.initial_cost);
  // The gauge vertex did not move.
  EXPECT_LT((graph.Pose(0).ToVector() - graph.RawPose(0).ToVector()).norm(), 1e-12);
}

TEST(G2oData, SphereBignoiseConverges) {
  SL_REQUIRE_DATA("pose_graphs/sphere_bignoise_vertex3.g2o");
  PoseGraph graph = ReadG2o(Graphs() / "sphere_bignoise_vertex3.g2o");
  EXPECT_EQ(graph.num_vertices(), 2200u);
  // A hard instance (big initial noise): LM needs ~170 iterations (~35 s CPU).
  PoseGraphOptions options = PlainOptions();
  options.max_iterations = 300;
  const PoseGraphSummary s = graph.Optimize(options);
  std::cerr << s.BriefReport() << "\n";
  EXPECT_EQ(s.status, PoseGraphStatus::kConverged);
  EXPECT_LT(s.final_cost, 0.5 * s.initial_cost);
}

// sphere2500 has edges only (TORO EDGE3); the ground truth file is the same graph with exact
// measurements, so chaining its odometry gives the true poses.
TEST(G2oData, Sphere2500AteFarBelowInitialGuess) {
  SL_REQUIRE_DATA("pose_graphs/sphere2500.txt");
  PoseGraph graph = ReadG2o(Graphs() / "sphere2500.txt");
  const PoseGraph gt = ReadG2o(Graphs() / "sphere2500_groundtruth.txt");
  ASSERT_EQ(graph.num_vertices(), gt.num_vertices());
  auto ate = [&](const PoseGraph& g) {
    std::vector<Eigen::Vector3d> est, ref;
    for (int64_t id : g.VertexIds()) {
      est.push_back(g.Pose(id).translation);
      ref.push_back(gt.Pose(id).translation);
    }
    const AlignmentResult a = Umeyama(est, ref, Alignment::kSE3);
    return a.rms_residual;
  };
  const double ate_before = ate(graph);
  const PoseGraphSummary s = graph.Optimize(PlainOptions());
  const double ate_after = ate(graph);
  std::cerr << s.BriefReport() << "\n"
            << "sphere2500 ATE (SE3-aligned RMSE): initial " << ate_before << ", optimised "
            << ate_after << "\n";
  EXPECT_NE(s.status, PoseGraphStatus::kFailed);
  EXPECT_LT(s.final_cost, s.initial_cost);
  EXPECT_LT(ate_after, 0.1 * ate_before);
}

TEST(G2oData, TwoDimensionalGraphsLoadAndImprove) {
  SL_REQUIRE_DATA("pose_graphs/intel.g2o");
  for (const char* name : {"intel.g2o", "manhattan.g2o", "kitti_00.g2o"}) {
    PoseGraph graph = ReadG2o(Graphs() / name);
    EXPECT_EQ(graph.vertex_type(), VertexType::kSe2) << name;
    PoseGraphOptions options = PlainOptions();
    options.max_iterations = 50;
    const PoseGraphSummary s = graph.Optimize(options);
    std::cerr << name << ": " << s.BriefReport() << "\n";
    EXPECT_NE(s.status, PoseGraphStatus::kFailed) << name;
    EXPECT_LT(s.final_cost, s.initial_cost) << name;
    // Planar vertices stay planar.
    for (int64_t id : graph.VertexIds()) {
      ASSERT_NEAR(graph.Pose(id).translation.z(), 0.0, 1e-9) << name;
    }
  }
}

TEST(G2oData, SmallFilesRoundTrip) {
  SL_REQUIRE_DATA("pose_graphs/tinyGrid3D.g2o");
  for (const char* name : {"tinyGrid3D.g2o", "pose3example.txt"}) {
    const PoseGraph graph = ReadG2o(Graphs() / name);
    std::stringstream ss;
    WriteG2o(ss, graph);
    const PoseGraph again = ReadG2o(ss, "roundtrip");
    ASSERT_EQ(again.num_vertices(), graph.num_vertices());
    ASSERT_EQ(again.edges().size(), graph.edges().size());
    for (int64_t id : graph.VertexIds()) {
      EXPECT_LT((again.Pose(id).ToMatrix4() - graph.Pose(id).ToMatrix4()).norm(), 1e-12);
    }
    for (size_t k = 0; k < graph.edges().size(); ++k) {
      EXPECT_LT((again.edges()[k].information - graph.edges()[k].information).norm(),
                1e-9 * graph.edges()[k].information.norm());
    }
  }
}

}  // namespace
}  // namespace sparseloop
