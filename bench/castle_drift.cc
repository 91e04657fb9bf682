// The castle ring family under a rotation bias about each camera axis (docs/POSEGRAPH.md,
// "Under pitch and roll"; `scripts/benchmark --family` puts it into
// docs/BENCHMARKS_DRIFT.md):
// `sparseloop run`'s pipeline (RunPipeline, no depths, the options below) on castle_p30_768's 30
// views with raw poses drifted from the exact ones (test::DriftCastle: a bias per keyframe about
// camera x pitch, y yaw or z roll, a scale growth per keyframe and seeded per-step noise). Per
// case: raw and corrected Sim(3) ATE and every loop with the measurement it used (loops.csv's
// pose_kind, plus the verification method) and its error against the exact relative pose. ONE
// JSON object on stdout, or with --markdown a table. Runtime ~3 s per case on one core (81 cases
// by default).
//   build/bin/castle_drift [--data DIR] [--axes pitch,yaw,roll] [--biases 0.2,0.5,1]
//                          [--scales 1,0.99,1.01] [--seeds 11,12,13] [--config FILE]
//                          [--set KEY=VALUE]... [--write-trajectories DIR] [--markdown]
// DIR defaults to $SPARSELOOP_DATA, else the configured SPARSELOOP_DATA_DIR. Exit 0 on success,
// 2 on a bad argument, missing data or any other error. --write-trajectories DIR also writes each
// case's raw and GT poses (KITTI rows, DIR/AXIS_BIAS_SCALE_SEED_{raw,gt}.txt) for
// `posegraph_accuracy --oracle` (exact loops at the ring closure on the same raw poses).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "castle_input.h"
#include "program_main.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/pipeline.h"

namespace sparseloop {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

double Deg(double rad) { return rad * 180.0 / M_PI; }

const std::vector<std::string> kAxisNames = {"pitch", "yaw", "roll"};  // camera x, y, z

double Ate(const Trajectory& gt, const Trajectory& est) {
  EvaluationOptions options;
  options.compute_rpe = false;
  options.compute_kitti = false;
  return EvaluateTrajectory(gt, est, options).ate.rmse;
}

// One loop against the exact relative pose: rotation error, translation direction error and, for
// a metric pose, the length of the estimated translation (raw units of the match) and the GT's.
json LoopRow(const Trajectory& gt, const LoopResult& loop, bool accepted) {
  const Rigid3d& world_from_match = gt.poses.at(loop.match_id).world_from_cam;
  const Rigid3d& world_from_query = gt.poses.at(loop.query_id).world_from_cam;
  const Rigid3d exact = world_from_match.Inverse() * world_from_query;
  const Eigen::Vector3d& t = loop.match_from_query.translation;
  json row = {
      {"query", loop.query_id},
      {"match", loop.match_id},
      {"accepted", accepted},
      {"pose_kind", ToString(loop.pose_kind)},
      {"method", ToString(loop.method)},
      {"inliers", loop.inliers},
      {"local_map_points", loop.local_map_points},
      {"local_map_inliers", loop.local_map_inliers},
      {"local_poses_from_images", loop.local_poses_from_images},
      {"local_poses_raw", loop.local_poses_raw},
      {"rotation_error_deg", Deg(RotationAngle(exact.rotation, loop.match_from_query.rotation))},
      {"translation_direction_error_deg",
       Deg(std::acos(std::clamp(t.normalized().dot(exact.translation.normalized()), -1.0, 1.0)))},
      {"translation_length", t.norm()},
      {"exact_translation_length_m", exact.translation.norm()}};
  return row;
}

json RunCase(const test::CastleRing& castle, int axis, double bias_deg, double scale_step,
             uint64_t seed, const PipelineOptions& options, const fs::path& write_dir) {
  test::CastleDrift spec;
  spec.bias_deg = bias_deg * Eigen::Vector3d::Unit(axis);
  spec.scale_step = scale_step;
  spec.seed = seed;
  const Trajectory raw = test::DriftCastle(castle.gt, spec);
  if (!write_dir.empty()) {
    // KITTI rows, raw and GT associated by row (posegraph_accuracy --oracle reads them).
    const std::string stem =
        fmt::format("{}_{:g}_{:g}_{}", kAxisNames[axis], bias_deg, scale_step, seed);
    WriteTrajectory(write_dir / (stem + "_raw.txt"), raw, TrajectoryFormat::kKitti);
    WriteTrajectory(write_dir / (stem + "_gt.txt"), castle.gt, TrajectoryFormat::kKitti);
  }
  const PipelineResult result = RunPipeline(castle.dataset, raw, options);
  json loops = json::array();
  for (size_t i = 0; i < result.loops.size(); ++i)
    loops.push_back(LoopRow(castle.gt, result.loops[i], result.loop_accepted[i]));
  const double raw_ate = Ate(castle.gt, raw);
  const double corrected_ate = Ate(castle.gt, result.corrected);
  return {{"axis", kAxisNames[axis]},
          {"bias_deg_per_keyframe", bias_deg},
          {"scale_step", scale_step},
          {"seed", seed},
          {"raw_ate_m", raw_ate},
          {"corrected_ate_m", corrected_ate},
          {"ratio", corrected_ate / raw_ate},
          {"loops", loops}};
}

// "29->2 se3_metric" per accepted loop of a case; "none" without one.
std::string AcceptedLoops(const json& c) {
  std::string s;
  for (const json& l : c["loops"]) {
    if (!l["accepted"].get<bool>()) continue;
    if (!s.empty()) s += ", ";
    s += fmt::format("{}->{} {}", l["query"].get<int64_t>(), l["match"].get<int64_t>(),
                     l["pose_kind"].get<std::string>());
  }
  return s.empty() ? "none" : s;
}

// The docs table: one row per axis / bias / scale, the seeds side by side.
std::string Markdown(const json& cases) {
  std::map<std::tuple<int, double, double>, std::vector<json>> groups;
  for (const json& c : cases) {
    const int axis = static_cast<int>(
        std::find(kAxisNames.begin(), kAxisNames.end(), c["axis"].get<std::string>()) -
        kAxisNames.begin());
    groups[{axis, c["bias_deg_per_keyframe"].get<double>(), c["scale_step"].get<double>()}]
        .push_back(c);
  }
  std::string md =
      "| axis | bias deg / kf | scale / kf | corrected / raw ATE (per seed) | <= 40 % | "
      "accepted loops (per seed) | loop rotation error deg | loop direction error deg |\n"
      "|---|---|---|---|---|---|---|---|\n";
  int met = 0, total = 0;
  for (const auto& [key, group] : groups) {
    const auto& [axis, bias, scale] = key;
    std::string ratios, loops;
    int below = 0;
    std::vector<double> rot, dir;
    for (const json& c : group) {
      const double ratio = c["ratio"].get<double>();
      ratios += fmt::format("{}{:.2f}", ratios.empty() ? "" : " / ", ratio);
      loops += fmt::format("{}{}", loops.empty() ? "" : "; ", AcceptedLoops(c));
      below += ratio <= 0.4 ? 1 : 0;
      for (const json& l : c["loops"]) {
        if (!l["accepted"].get<bool>()) continue;
        rot.push_back(l["rotation_error_deg"].get<double>());
        dir.push_back(l["translation_direction_error_deg"].get<double>());
      }
    }
    met += below;
    total += static_cast<int>(group.size());
    const auto range = [](std::vector<double> v) {
      if (v.empty()) return std::string("-");
      std::sort(v.begin(), v.end());
      return v.front() == v.back() || v.size() == 1
                 ? fmt::format("{:.2f}", v.front())
                 : fmt::format("{:.2f}-{:.2f}", v.front(), v.back());
    };
    md += fmt::format("| {} | {:g} | {:g} | {} | {}/{} | {} | {} | {} |\n", kAxisNames[axis], bias,
                      scale, ratios, below, group.size(), loops, range(rot), range(dir));
  }
  md += fmt::format("\n{} of {} cases at or below 40 % of the raw ATE.\n", met, total);
  return md;
}

std::vector<double> ParseList(const std::string& flag, const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    size_t used = 0;
    try {
      v.push_back(std::stod(item, &used));
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size())
      throw std::invalid_argument(flag + " expects comma-separated numbers, got '" + text + "'");
  }
  return v;
}

int Main(int argc, char** argv) {
  fs::path data = test::DataDir();
  std::vector<int> axes = {0, 1, 2};
  std::vector<double> biases = {0.2, 0.5, 1.0}, scales = {1.0, 0.99, 1.01}, seeds = {11, 12, 13};
  PipelineOptions options;
  bool markdown = false;
  fs::path write_dir;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--data" && has_value) {
      data = argv[++i];
    } else if (a == "--axes" && has_value) {
      axes.clear();
      std::stringstream ss(argv[++i]);
      for (std::string name; std::getline(ss, name, ',');) {
        const auto it = std::find(kAxisNames.begin(), kAxisNames.end(), name);
        if (it == kAxisNames.end())
          throw std::invalid_argument("--axes: unknown axis '" + name + "' (pitch, yaw, roll)");
        axes.push_back(static_cast<int>(it - kAxisNames.begin()));
      }
    } else if (a == "--biases" && has_value) {
      biases = ParseList(a, argv[++i]);
    } else if (a == "--scales" && has_value) {
      scales = ParseList(a, argv[++i]);
    } else if (a == "--seeds" && has_value) {
      seeds = ParseList(a, argv[++i]);
    } else if (a == "--config" && has_value) {
      LoadConfigFile(argv[++i], &options);
    } else if (a == "--set" && has_value) {
      const std::string kv = argv[++i];
      const size_t eq = kv.find('=');
      if (eq == std::string::npos) throw std::invalid_argument("--set expects KEY=VALUE");
      ApplyConfigOverride(kv.substr(0, eq), kv.substr(eq + 1), &options);
    } else if (a == "--write-trajectories" && has_value) {
      write_dir = argv[++i];
      fs::create_directories(write_dir);
    } else if (a == "--markdown") {
      markdown = true;
    } else if (a == "--help" || a == "-h") {
      std::printf(
          "usage: castle_drift [--data DIR] [--axes pitch,yaw,roll] [--biases 0.2,0.5,1] "
          "[--scales 1,0.99,1.01] [--seeds 11,12,13] [--config FILE] [--set KEY=VALUE]... "
          "[--write-trajectories DIR] [--markdown]\n");
      return 0;
    } else {
      std::fprintf(stderr, "castle_drift: unknown argument '%s' (try --help)\n", a.c_str());
      return 2;
    }
  }
  options.Check();
  if (!fs::exists(data / "castle_p30_768" / "images" / "0029.jpg")) {
    std::fprintf(stderr,
                 "castle_drift: real data not found: %s (pass --data DIR or set SPARSELOOP_DATA "
                 "to the shared data folder)\n",
                 (data / "castle_p30_768").string().c_str());
    return 2;
  }
  cv::setNumThreads(1);
  const test::CastleRing castle = test::LoadCastleRing(data / "castle_p30_768");
  json cases = json::array();
  for (const int axis : axes) {
    for (const double bias : biases) {
      for (const double scale : scales) {
        for (const double seed : seeds) {
          cases.push_back(
              RunCase(castle, axis, bias, scale, static_cast<uint64_t>(seed), options, write_dir));
          const json& c = cases.back();
          std::cerr << fmt::format(
              "{} {:g} deg x{:g} seed {:g}: {:.3f} -> {:.3f} m ({:.0f} %), {}\n", kAxisNames[axis],
              bias, scale, seed, c["raw_ate_m"].get<double>(), c["corrected_ate_m"].get<double>(),
              100.0 * c["ratio"].get<double>(), AcceptedLoops(c));
        }
      }
    }
  }
  if (markdown) {
    std::cout << Markdown(cases);
  } else {
    std::cout << json{{"data", data.string()}, {"config", ConfigToJson(options)}, {"cases", cases}}
                     .dump(1)
              << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace sparseloop

int main(int argc, char** argv) {
  return sparseloop::test::RunProgram("castle_drift", 2,
                                      [&] { return sparseloop::Main(argc, argv); });
}
