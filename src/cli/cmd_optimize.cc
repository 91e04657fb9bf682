// sparseloop optimize: read a g2o / TORO pose graph, optimise it, print a Ceres-style brief
// report and write the optimised graph (g2o, atomically).
#include <cmath>
#include <iostream>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/timer.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/posegraph/g2o.h"

namespace sparseloop::cli {

int RunOptimize(int argc, char** argv) {
  CLI::App app{
      "Optimise a pose graph (g2o: VERTEX_SE3:QUAT / EDGE_SE3:QUAT / VERTEX_SE2 / "
      "EDGE_SE2; TORO EDGE3)"};
  std::string in;
  std::string out;
  std::string robust = "trivial";
  PoseGraphOptions options;
  options.rejection = OutlierRejection::kNone;  // g2o files do not mark loops
  app.add_option("--g2o", in, "input pose graph")->required();
  app.add_option("--out", out, "output g2o file (written atomically)")->required();
  app.add_option("--robust", robust,
                 "robust loss on every edge: trivial (default; also 'none'), huber, cauchy");
  app.add_option("--loss-scale", options.loss_scale,
                 "where the robust loss bends, in whitened residual units (default 1)");
  app.add_option("--max-iterations", options.max_iterations, "Levenberg-Marquardt iterations")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
  app.add_option("--threads", options.num_threads, "Ceres threads")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
  bool quiet = false;
  app.add_flag("--quiet", quiet,
               "No progress on stderr (reading, solving, one line per iteration)");
  Parse(app, argc, argv);
  CheckOutputsAreNotInputs({{"--out", out}}, {{"--g2o", in}});
  CheckOutputFileFlag("--out", out);

  // The loss names of the config (ToString(RobustLoss)); "none" is the older name of trivial.
  std::optional<RobustLoss> loss;
  for (RobustLoss l : {RobustLoss::kTrivial, RobustLoss::kHuber, RobustLoss::kCauchy})
    if (robust == ToString(l)) loss = l;
  if (robust == "none") loss = RobustLoss::kTrivial;
  SL_CHECK_MSG(loss.has_value(), "--robust must be trivial (or none), huber or cauchy, got '{}'",
               robust);
  options.edge_loss = *loss;
  options.loop_loss = *loss;
  SL_CHECK_MSG(options.num_threads <= 256, "--threads must be in [1, 256], got {}",
               options.num_threads);
  CheckNamingFlags({{"loss_scale", "--loss-scale"},
                    {"max_iterations", "--max-iterations"},
                    {"num_threads", "--threads"}},
                   [&] { options.Check(); });

  // Progress on stderr: a large graph takes tens of seconds (one line per Levenberg-Marquardt
  // iteration from the pose graph's log).
  Timer timer;
  if (!quiet) Logger().info("optimize: reading {}", in);
  PoseGraph graph = ReadG2o(in);
  if (!quiet) {
    Logger().info(
        "optimize: {} vertices, {} edges read in {:.1f} s; solving (at most {} "
        "iterations)",
        graph.num_vertices(), graph.edges().size(), timer.ElapsedMs() / 1000.0,
        options.max_iterations);
  }
  options.log_progress = !quiet;
  const PoseGraphSummary summary = graph.Optimize(options);
  if (summary.status == PoseGraphStatus::kFailed || !std::isfinite(summary.final_cost)) {
    std::cerr << fmt::format("optimize: the solve failed ({}; final cost {}): {} not written\n",
                             summary.ceres_message, summary.final_cost, out);
    return 1;
  }
  WriteFileAtomically(out, [&](std::ostream& os) { WriteG2o(os, graph); });

  std::cout << fmt::format(
      "Pose graph optimisation report\n"
      "  input        {}\n"
      "  vertices     {} ({})\n"
      "  edges        {}\n"
      "  robust loss  {}\n"
      "Cost:\n"
      "  initial      {:.6e}\n"
      "  final        {:.6e}\n"
      "  change       {:.6e}\n"
      "Minimizer iterations  {}\n"
      "Time (s)              {:.3f}\n"
      "Termination:          {} ({})\n"
      "wrote {}\n",
      in, summary.num_vertices, graph.vertex_type() == VertexType::kSe2 ? "SE2" : "SE3",
      summary.num_edges, robust, summary.initial_cost, summary.final_cost,
      summary.initial_cost - summary.final_cost, summary.iterations, summary.solve_seconds,
      ToString(summary.status), summary.ceres_message, out);
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("optimize", "optimise a g2o pose graph and write the result",
                            RunOptimize);

}  // namespace sparseloop::cli
