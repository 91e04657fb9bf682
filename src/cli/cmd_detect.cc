// sparseloop detect: run the loop detector over an image dataset and write the loops it finds.
// Parses arguments, calls the library's offline driver with the optimiser off (RunDetection, the
// driver of `run`), prints and writes files.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "cli/run_output.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/pipeline.h"

namespace sparseloop::cli {

namespace {

// Every file `detect` writes into --out.
const std::vector<std::string> kDetectOutputFiles = {"loops.csv", "summary.json", "frames.csv",
                                                     "timings.csv"};

// What the user reads on stdout: counts, why nothing was found, the loops.
void PrintDetectSummary(const nlohmann::json& summary, const PipelineResult& result,
                        const std::vector<LoopResult>& loops, const PipelineOptions& options,
                        bool have_poses) {
  const size_t keyframes = std::max<size_t>(1, result.frame_results.size());
  std::cout << fmt::format("{} keyframes, {} loops, {:.0f} bytes/keyframe, {:.1f} ms/keyframe\n",
                           result.frame_results.size(), loops.size(), result.bytes_per_keyframe,
                           1000.0 * result.detect_seconds / keyframes);
  // Why nothing (or little) was found: the status of every frame, counted.
  std::string statuses;
  for (const auto& [status, count] : summary["status_counts"].items()) {
    if (count.get<int>() > 0)
      statuses += fmt::format("{}{} {}", statuses.empty() ? "" : ", ", status, count.get<int>());
  }
  std::cout << "frames by status: " << statuses << " (per frame: frames.csv)\n";
  if (loops.empty() &&
      summary["status_counts"]["no_candidates"].get<size_t>() == result.frame_results.size()) {
    std::cout << fmt::format(
        "no frame had a candidate to match: the {} frames just before each query are never "
        "searched (--exclude-recent {}){}\n",
        options.detector.search.exclude_recent, options.detector.search.exclude_recent,
        have_poses ? ", and the search area / --min-path-ratio left none" : "");
  }
  for (const auto& l : loops)
    std::cout << fmt::format("loop {} -> {}{}  inliers {}  score {:.3f}\n", l.query_id, l.match_id,
                             l.match_session ? fmt::format(" (session {})", l.match_session) : "",
                             l.inliers, l.score);
}

}  // namespace

int RunDetect(int argc, char** argv) {
  CLI::App app{"Detect loop closures in an image sequence (writes loops.csv and summary.json)"};
  DetectorFlags flags;
  AddDetectorFlags(app, &flags);
  std::string map_path;
  app.add_option("--map", map_path,
                 "persistent map (SQLite): earlier sessions in it are searched too (multi-session "
                 "loops, loops.csv match_session > 0); this run is stored as a new session");
  Parse(app, argc, argv);
  // No input written over first (the more important message), then the output folder itself.
  std::vector<NamedPath> inputs = {{"--config", flags.config}, {"--poses", flags.poses}};
  for (const NamedPath& map : MapFiles("--map", map_path)) inputs.push_back(map);
  CheckOutputsAreNotInputs(FilesIn("--out", flags.out, kDetectOutputFiles), inputs);
  CheckOutputDirFlag("--out", flags.out, kDetectOutputFiles);

  const bool poses_given = !flags.poses.empty() || DatasetHasPoseTopic(flags.dataset);
  // Without poses only the global search is defined: an explicit other --search is an error
  // (PipelineOptionsFromFlags switches the configured default to global).
  if (!poses_given && !flags.detector.search.empty() && flags.detector.search != "global") {
    throw std::invalid_argument(
        fmt::format("--search {} needs poses (--poses FILE); without poses use --search global",
                    flags.detector.search));
  }
  PipelineOptions options = PipelineOptionsFromFlags(flags);
  options.map_path = map_path;
  options.session_label = "detect " + flags.dataset;
  options.Check();

  const Dataset dataset = OpenDatasetFromFlags(flags);
  SL_CHECK_MSG(!dataset.frames.empty(), "dataset '{}' has no frames", flags.dataset);
  // Raw poses come only from --poses or a rosbag: pose topic: a dataset's own ground truth (KITTI
  // poses.txt, a render's poses.txt) is never searched with as if a vSLAM had produced it.
  const std::optional<Trajectory> raw =
      RawPosesForFrames(flags.poses, dataset, options.raw_association_max_dt);
  const bool have_poses = raw.has_value();
  if (!have_poses) {
    Logger().warn("no --poses for '{}': no raw poses, using the global search area{}",
                  flags.dataset,
                  dataset.has_gt() ? " (the dataset's ground truth is not used as raw poses)" : "");
  }
  // Every input is read: the folder now holds this run only.
  PrepareRunFolder(flags.out, "detect", flags.dataset, kDetectOutputFiles,
                   {flags.config, flags.poses, map_path});

  ProgressLine progress("detect", flags.quiet);
  const PipelineResult result = RunDetection(dataset, raw, options, [&](const PipelineProgress& p) {
    progress.Update(p.frames_done, p.frames_total, p.loops);
  });
  progress.Finish();

  // In-session loops first, then loops into earlier map sessions (as `run` writes them).
  std::vector<LoopResult> loops = result.loops;
  loops.insert(loops.end(), result.cross_session_loops.begin(), result.cross_session_loops.end());
  const std::filesystem::path out = ResolvedPath(flags.out);  // DIR/missing/.. is DIR
  std::filesystem::create_directories(out);
  WriteLoopsCsv(out / "loops.csv", loops, nullptr, nullptr, ImageNamesByFrame(dataset),
                /*graph_columns=*/false);
  WriteFramesCsv(out / "frames.csv", result.frame_results);
  WriteTimingsCsv(out / "timings.csv", result.frame_results);
  nlohmann::json summary = DetectionSummaryJson(result, loops.size());
  summary["command"] = "detect";
  summary["dataset"] = flags.dataset;
  if (have_poses)
    summary["poses_file"] = flags.poses.empty() ? dataset.raw_poses_source : flags.poses;
  summary["skipped_frames"] = result.skipped_frames;
  summary["features_per_keyframe"] = options.detector.features.max_features;
  summary["search"] = ToString(options.detector.search.strategy);
  summary["pose_kind"] = loops.empty() ? "none" : ToString(loops.front().pose_kind);
  summary["planar_alternatives"] = std::count_if(
      loops.begin(), loops.end(), [](const LoopResult& l) { return l.planar_alternative; });
  summary["total_ms"] = 1000.0 * result.detect_seconds;
  summary["cross_session_loops"] = result.cross_session_loops.size();
  if (!map_path.empty()) {
    summary["map"] = {{"path", map_path},
                      {"session", result.map_session},
                      {"prior_keyframes", result.prior_keyframes}};
  }
  summary["config"] = ConfigToJson(options)["detector"];
  WriteFileAtomically(out / "summary.json", [&](std::ostream& os) { os << JsonText(summary); });
  PrintDetectSummary(summary, result, loops, options, have_poses);
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("detect", "detect loop closures in an image sequence", RunDetect);

}  // namespace sparseloop::cli
