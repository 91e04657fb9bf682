#pragma once
// Shared by `detect` and `run`: dataset/detector flags, the progress line, and the output files
// (loops.csv, timings.csv, summary.json fields). Formatting only; the algorithms live in the
// library.
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "sparseloop/eval/loops.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/pipeline.h"

namespace sparseloop::cli {

// Detector options set by flags of `detect` and `run`, applied over the defaults and --config.
struct DetectorOverrides {
  std::optional<int> k;                  // -K,--features
  std::string search;                    // --search paper | radius | global (empty: keep)
  std::optional<int> exclude_recent;     // --exclude-recent (search.exclude_recent)
  std::optional<double> min_path_ratio;  // --min-path-ratio
  std::vector<std::string> set;          // --set KEY=VALUE (any configuration key), in order
};

struct DetectorFlags {
  std::string dataset;     // kitti:DIR | tum:DIR | euroc:DIR | images:DIR
  std::string poses;       // raw vSLAM poses
  std::string intrinsics;  // fx,fy,cx,cy
  DetectorOverrides detector;
  std::optional<std::string> preset;  // a shipped preset (PresetNames), applied before --config
  std::string config;                 // JSON configuration file
  std::string out;                    // output directory
  bool quiet = false;                 // no progress line
};

void AddDetectorFlags(CLI::App& app, DetectorFlags* flags);
// "fx,fy,cx,cy" -> intrinsics; std::invalid_argument naming --intrinsics when malformed or invalid.
CameraIntrinsics ParseIntrinsicsFlag(const std::string& text);
// -K,--features, --search, --exclude-recent and --min-path-ratio, shared by `detect` and `run`:
// help shows the detector's defaults.
void AddDetectorOverrideFlags(CLI::App& app, DetectorOverrides* overrides);
// Applies the flags given to `options` and checks them; an invalid value names its flag.
void ApplyDetectorOverrides(const DetectorOverrides& overrides, LoopDetector::Options* options);
// Applies each --set KEY=VALUE in order (ApplyConfigOverride), checking the options after each;
// std::invalid_argument naming the --set argument.
void ApplySetFlags(const std::vector<std::string>& set, PipelineOptions* options);
// Defaults, then --preset, then --config, then the explicit flags (-K, --search, ...), then each
// --set in order. True when --dataset is a rosbag: spec naming a pose=TOPIC (raw poses without
// --poses).
bool DatasetHasPoseTopic(const std::string& dataset_spec);
PipelineOptions PipelineOptionsFromFlags(const DetectorFlags& flags);
Dataset OpenDatasetFromFlags(const DetectorFlags& flags);

// A run folder holds one run. Before any work: refuses `out` equal to the dataset's folder (the
// next run would read its outputs as input), refuses a non-empty `out` that is not a previous
// output of `command` (its summary.json says "command": command, or it holds only files the
// command writes and `inputs`: the --config / --poses / --gt / --map files the user placed
// there), and otherwise deletes the files of the previous run that `files` names (plus
// report.html / report_*.png, which describe it) and logs which. std::invalid_argument naming
// --out (exit 2) when refused.
// "--out DIR: expected an empty folder or the output of an earlier `sparseloop COMMAND`, got
// WHAT; choose another --out", the refusal of PrepareRunFolder and of render's own folder rule.
std::invalid_argument NotAnEarlierOutput(const std::string& out, const std::string& command,
                                         const std::string& what);
// "a folder holding N other entr(y|ies) (FIRST[, ...])", the entries sorted.
std::string OtherEntries(std::vector<std::string> entries);

void PrepareRunFolder(const std::string& out, const std::string& command,
                      const std::string& dataset_spec, const std::vector<std::string>& files,
                      const std::vector<std::string>& inputs);

// A trajectory `run` builds on must carry orientations: FileError-based std::invalid_argument
// naming `flag` and the file for a positions-only one.
void RequireOrientations(const std::string& flag, const std::string& path, const Trajectory& t);
// The raw vSLAM pose of every frame (run and detect): --poses when given (`poses_flag`), else the
// rosbag: dataset's pose topic; matched to the frames by MatchRawPosesToFrames. Empty when there
// is neither (never the dataset's ground truth).
std::optional<Trajectory> RawPosesForFrames(const std::string& poses_flag, const Dataset& dataset,
                                            double max_dt);

// A one-line progress display on stderr when stderr is a terminal; silent otherwise.
class ProgressLine {
 public:
  explicit ProgressLine(std::string label, bool quiet = false);
  void Update(size_t done, size_t total, size_t loops);
  void Finish();

 private:
  std::string label_;
  bool enabled_ = false;
  double start_s_ = 0.0;
  double last_s_ = -1.0;
};

// loops.csv, for run and detect (one writer; docs/FORMATS.md):
// query,match,score,inliers,status,pose_kind,planar_alternative,accepted,correct,qx,qy,qz,qw,tx,
// ty,tz,scale,match_session (planar_alternative 0/1: LoopResult::planar_alternative; accepted /
// correct are empty when unknown, including rows past the end of
// `accepted` / `truth`; match_session: this run's is 0, an earlier map session's > 0). Without
// `graph_columns` (detect: no pose graph) the accepted and correct columns are left out.
// Last two columns query_image, match_image: the frames' image file names (no folder) from
// `images` (frame index -> name; empty when unknown, e.g. a match in an earlier map session).
using ImageNames = std::map<int64_t, std::string>;
ImageNames ImageNamesByFrame(const Dataset& dataset);
void WriteLoopsCsv(const std::filesystem::path& path, const std::vector<LoopResult>& loops,
                   const std::vector<bool>* accepted, const LoopTruth* truth,
                   const ImageNames& images, bool graph_columns = true);
// The image name columns of one loops.csv row: ",query_image,match_image".
std::string ImageColumns(const LoopResult& loop, const ImageNames& images);
// frames.csv: why each processed frame did or did not close a loop, one row per frame:
// frame,status,candidates,matches,inliers,match,source,verified_area,verified_appearance,
// appearance_candidates,pose_segment,pose_reset,area (area: LoopResult::area as ids and
// ranges, FormatIdRanges; match
// -1 when no candidate was matched; source "area" / "appearance" on detected rows, else empty;
// the keyframe ids geometrically verified, ';'-separated, LoopResult::verified_in_area /
// verified_by_appearance).
void WriteFramesCsv(const std::filesystem::path& path, const std::vector<LoopResult>& results);
// {"status": count} over `results` (every status name, 0 included).
nlohmann::json StatusCountsJson(const std::vector<LoopResult>& results);
// Detected loops per LoopResult::source ("area", "appearance"; both keys, 0 included).
nlohmann::json SourceCountsJson(const std::vector<LoopResult>& results);
// timings.csv: one row per processed keyframe: keyframe,status,extract_ms,search_ms,match_ms,
// verify_ms,total_ms (only millisecond columns besides the first two; report.py plots each).
void WritePrCurveCsv(const std::filesystem::path& path, const LoopPrResult& pr);
void WriteTimingsCsv(const std::filesystem::path& path, const std::vector<LoopResult>& results);
// keyframes, loops, bytes_per_keyframe, status_counts, mapped_pixels {keyframes,
// keyframes_without_depth} and timing_ms {stage: {median,p90,p99,max}} of a run's result.
nlohmann::json DetectionSummaryJson(const PipelineResult& result, size_t loops);
void AddLoopTruthJson(nlohmann::json& summary, const LoopTruth& truth,
                      const std::vector<bool>& accepted);
void PrintRunSummary(std::ostream& os, const nlohmann::json& summary,
                     const TrajectoryEvaluation* raw, const TrajectoryEvaluation* corrected);

}  // namespace sparseloop::cli
