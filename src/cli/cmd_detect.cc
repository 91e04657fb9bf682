// sparseloop detect: run the loop detector over an image dataset and write the loops it finds.
// Parses arguments, calls the library (io: dataset; loop: detector), prints and writes files.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "cli/run_output.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/statistics.h"
#include "sparseloop/core/timer.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/map/map_database.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/dataset_source.h"
#include "sparseloop/pipeline/map_records.h"

namespace sparseloop::cli {

namespace {

// Every file `detect` writes into --out.
const std::vector<std::string> kDetectOutputFiles = {"loops.csv", "summary.json", "frames.csv"};

nlohmann::json Stats(std::vector<double> values) {
  if (values.empty()) return {{"median", 0.0}, {"p90", 0.0}, {"max", 0.0}};
  std::sort(values.begin(), values.end());
  return {{"median", PercentileOfSorted(values, 0.5)},
          {"p90", PercentileOfSorted(values, 0.9)},
          {"max", values.back()}};
}

}  // namespace

int RunDetect(int argc, char** argv) {
  CLI::App app{"Detect loop closures in an image sequence (writes loops.csv and summary.json)"};
  std::string dataset_spec, poses, intrinsics_spec, config_path, out_dir, map_path;
  DetectorOverrides overrides;
  app.add_option("--dataset", dataset_spec,
                 "kitti:DIR | tum:DIR | euroc:DIR | images:DIR | "
                 "rosbag:FILE.bag?image=TOPIC[&pose=TOPIC&camera_info=TOPIC&gt=TOPIC]")
      ->required();
  app.add_option("--poses", poses, "raw vSLAM poses (any trajectory format), one per frame");
  app.add_option("--intrinsics", intrinsics_spec, "fx,fy,cx,cy (overrides the dataset's)");
  AddDetectorOverrideFlags(app, &overrides);
  app.add_option("--config", config_path, "JSON options ({\"detector\": {...}})");
  app.add_option("--out", out_dir, "output directory")->required();
  app.add_option("--map", map_path,
                 "persistent map (SQLite): earlier sessions in it are searched too (multi-session "
                 "loops, loops.csv match_session > 0); this run is stored as a new session");
  Parse(app, argc, argv);
  CheckOutputDirFlag("--out", out_dir, kDetectOutputFiles);

  PipelineOptions pipeline_options;
  if (!config_path.empty()) LoadConfigFile(config_path, &pipeline_options);
  ApplyDetectorOverrides(overrides, &pipeline_options.detector);
  ApplySetFlags(overrides.set, &pipeline_options);
  LoopDetector::Options options = pipeline_options.detector;

  DatasetOptions dataset_options;
  dataset_options.intrinsics_name = "--intrinsics";
  if (!intrinsics_spec.empty()) dataset_options.intrinsics = ParseIntrinsicsFlag(intrinsics_spec);
  Dataset dataset = OpenDatasetSpec(dataset_spec, dataset_options);
  SL_CHECK_MSG(!dataset.frames.empty(), "dataset '{}' has no frames", dataset_spec);
  // Raw poses come only from --poses or a rosbag: pose topic: a dataset's own ground truth (KITTI
  // poses.txt, a render's poses.txt) is never searched with as if a vSLAM had produced it (#21).
  const std::optional<Trajectory> raw =
      RawPosesForFrames(poses, dataset, pipeline_options.raw_association_max_dt);
  const bool have_poses = raw.has_value();
  if (!have_poses) {
    if (overrides.search.empty()) {
      options.search.strategy = SearchStrategy::kGlobal;
      Logger().warn(
          "no --poses for '{}': no raw poses, using the global search area{}", dataset_spec,
          dataset.has_gt() ? " (the dataset's ground truth is not used as raw poses)" : "");
    } else {
      SL_CHECK_MSG(options.search.strategy == SearchStrategy::kGlobal,
                   "--search {} needs poses (--poses FILE); without poses use --search global",
                   overrides.search);
    }
  }
  options.Check();
  // Every input is read: the folder now holds this run only.
  PrepareRunFolder(out_dir, "detect", dataset_spec, kDetectOutputFiles,
                   {config_path, poses, map_path});
  LoopDetector detector(options);

  // Multi-session: load the earlier sessions of the map, then store this run as a new one.
  std::unique_ptr<MapDatabase> map;
  int64_t map_session = 0;
  size_t prior_keyframes = 0;
  if (!map_path.empty()) {
    map = MapDatabase::Open(map_path);
    const float focal = static_cast<float>(0.5 * (dataset.intrinsics.fx + dataset.intrinsics.fy));
    prior_keyframes = LoadPriorSessions(*map, focal, &detector);
    map_session = map->BeginSession("detect " + dataset_spec);
  }

  std::filesystem::create_directories(out_dir);
  const bool progress = isatty(fileno(stderr));
  std::vector<LoopResult> loops, frame_results;
  std::vector<double> t_extract, t_search, t_match, t_verify, t_total;
  size_t bytes = 0;
  Timer wall;
  for (size_t i = 0; i < dataset.frames.size(); ++i) {
    const DatasetFrame& frame = dataset.frames[i];
    KeyframeInput input;
    input.id = frame.index;
    input.timestamp = frame.timestamp;
    input.image = ReadFrameGray(dataset, frame);
    if (input.image.empty()) throw FileError(frame.image_path.string(), 0, "a readable image");
    input.intrinsics = dataset.intrinsics;
    if (have_poses) input.world_from_cam = Sim3d(raw->poses[i].world_from_cam);
    const LoopResult r = detector.Process(input);
    const PackedKeyframe& stored = detector.packed_record(frame.index);
    bytes += stored.Bytes();
    if (map) map->PutRecord(map_session, stored);
    if (map && r.detected()) {
      map->PutLoop({map_session, r.query_id, r.match_session == 0 ? map_session : r.match_session,
                    r.match_id, r.inliers, r.score, r.match_from_query, true});
    }
    t_extract.push_back(r.timings.extract_ms);
    t_search.push_back(r.timings.search_ms);
    t_match.push_back(r.timings.match_ms);
    t_verify.push_back(r.timings.verify_ms);
    t_total.push_back(r.timings.total_ms);
    if (r.detected()) loops.push_back(r);
    frame_results.push_back(r);
    if (progress) {
      const double fps = (i + 1) / std::max(1e-9, wall.ElapsedMs() / 1000.0);
      std::fprintf(stderr, "\rdetect: frame %zu/%zu  %.1f frames/s  %zu loops", i + 1,
                   dataset.frames.size(), fps, loops.size());
    }
  }
  if (progress) std::fprintf(stderr, "\n");
  if (map) map->Flush();
  const double wall_ms = wall.ElapsedMs();

  const std::filesystem::path out(out_dir);
  WriteLoopsCsv(out / "loops.csv", loops, nullptr, nullptr, ImageNamesByFrame(dataset),
                /*graph_columns=*/false);
  WriteFramesCsv(out / "frames.csv", frame_results);
  nlohmann::json summary = {
      {"command", "detect"},
      {"dataset", dataset_spec},
      {"keyframes", dataset.frames.size()},
      {"loops", loops.size()},
      {"bytes_per_keyframe", double(bytes) / dataset.frames.size()},
      {"features_per_keyframe", options.features.max_features},
      {"search", ToString(options.search.strategy)},
      {"pose_kind", loops.empty() ? "none" : ToString(loops.front().pose_kind)},
      {"planar_alternatives",
       std::count_if(loops.begin(), loops.end(),
                     [](const LoopResult& l) { return l.planar_alternative; })},
      {"timing_ms",
       {{"extract", Stats(t_extract)},
        {"search", Stats(t_search)},
        {"match", Stats(t_match)},
        {"verify", Stats(t_verify)},
        {"total", Stats(t_total)}}},
      {"total_ms", wall_ms},
      {"status_counts", StatusCountsJson(frame_results)},
      {"loop_sources", SourceCountsJson(frame_results)},
      {"cross_session_loops",
       std::count_if(loops.begin(), loops.end(),
                     [](const LoopResult& l) { return l.match_session != 0; })},
  };
  if (map) {
    summary["map"] = {
        {"path", map_path}, {"session", map_session}, {"prior_keyframes", prior_keyframes}};
  }
  summary["config"] = ConfigToJson([&] {
    PipelineOptions p = pipeline_options;
    p.detector = options;
    return p;
  }())["detector"];
  WriteFileAtomically(out / "summary.json",
                      [&](std::ostream& os) { os << summary.dump(2) << "\n"; });
  std::cout << fmt::format("{} keyframes, {} loops, {:.0f} bytes/keyframe, {:.1f} ms/keyframe\n",
                           dataset.frames.size(), loops.size(),
                           double(bytes) / dataset.frames.size(), wall_ms / dataset.frames.size());
  // Why nothing (or little) was found: the status of every frame, counted.
  std::string statuses;
  for (const auto& [status, count] : summary["status_counts"].items()) {
    if (count.get<int>() > 0)
      statuses += fmt::format("{}{} {}", statuses.empty() ? "" : ", ", status, count.get<int>());
  }
  std::cout << "frames by status: " << statuses << " (per frame: frames.csv)\n";
  if (loops.empty() && summary["status_counts"]["no_candidates"].get<int>() ==
                           static_cast<int>(frame_results.size())) {
    std::cout << fmt::format(
        "no frame had a candidate to match: the {} frames just before each query are never "
        "searched (--exclude-recent {}){}\n",
        options.search.exclude_recent, options.search.exclude_recent,
        have_poses ? ", and the search area / --min-path-ratio left none" : "");
  }
  for (const auto& l : loops)
    std::cout << fmt::format("loop {} -> {}{}  inliers {}  score {:.3f}\n", l.query_id, l.match_id,
                             l.match_session ? fmt::format(" (session {})", l.match_session) : "",
                             l.inliers, l.score);
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("detect", "detect loop closures in an image sequence", RunDetect);

}  // namespace sparseloop::cli
