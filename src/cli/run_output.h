#pragma once
// Shared by `detect` and `run`: dataset/detector flags, the progress line, and the output files
// (loops.csv, timings.csv, summary.json fields). Formatting only; the algorithms live in the
// library.
#include <cstdio>
#include <filesystem>
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

struct DetectorFlags {
  std::string dataset;     // kitti:DIR | tum:DIR | euroc:DIR | images:DIR
  std::string poses;       // raw vSLAM poses
  std::string intrinsics;  // fx,fy,cx,cy
  std::optional<int> k;    // -K override (none: config / default)
  std::string search;      // paper | radius | global (empty: config / default)
  std::string config;      // JSON configuration file
  std::string out;         // output directory
  bool quiet = false;      // no progress line
};

void AddDetectorFlags(CLI::App& app, DetectorFlags* flags);
// -K,--features and --search, shared by `detect` and `run`: help shows the detector's defaults.
void AddFeaturesAndSearchFlags(CLI::App& app, std::optional<int>* k, std::string* search);
// Defaults, then --config, then the explicit flags (-K, --search).
PipelineOptions PipelineOptionsFromFlags(const DetectorFlags& flags);
Dataset OpenDatasetFromFlags(const DetectorFlags& flags);

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

// loops.csv:
// query,match,score,inliers,status,pose_kind,planar_alternative,accepted,correct,qx,qy,qz,qw,tx,
// ty,tz,scale,match_session (planar_alternative 0/1: LoopResult::planar_alternative; accepted /
// correct are empty when unknown, including rows past the end of
// `accepted` / `truth`; match_session 0 = this run, > 0 = an earlier map session).
void WriteLoopsCsv(const std::filesystem::path& path, const std::vector<LoopResult>& loops,
                   const std::vector<bool>* accepted, const LoopTruth* truth);
// timings.csv: one row per processed keyframe: keyframe,status,extract_ms,search_ms,match_ms,
// verify_ms,total_ms (only millisecond columns besides the first two; report.py plots each).
void WritePrCurveCsv(const std::filesystem::path& path, const LoopPrResult& pr);
void WriteTimingsCsv(const std::filesystem::path& path, const std::vector<LoopResult>& results);
// keyframes, loops, bytes_per_keyframe, status_counts and timing_ms {stage: {median,p90,p99,max}}.
nlohmann::json DetectionSummaryJson(const std::vector<LoopResult>& results, size_t loops,
                                    double bytes_per_keyframe);
void AddLoopTruthJson(nlohmann::json& summary, const LoopTruth& truth,
                      const std::vector<bool>& accepted);
void PrintRunSummary(std::ostream& os, const nlohmann::json& summary,
                     const TrajectoryEvaluation* raw, const TrajectoryEvaluation* corrected);

}  // namespace sparseloop::cli
