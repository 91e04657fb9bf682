#include "cli/run_output.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>

#include <fmt/ranges.h>
#include "cli/cli_util.h"

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/statistics.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/rosbag_spec.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/dataset_source.h"
#include "sparseloop/search/search_area.h"

namespace sparseloop::cli {
namespace {

double NowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Stats {
  double median = 0, p90 = 0, p99 = 0, max = 0, mean = 0;
};
Stats ComputeStats(std::vector<double> v) {
  Stats s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.median = PercentileOfSorted(v, 0.5);
  s.p90 = PercentileOfSorted(v, 0.9);
  s.p99 = PercentileOfSorted(v, 0.99);
  s.max = v.back();
  double sum = 0;
  for (double x : v) sum += x;
  s.mean = sum / v.size();
  return s;
}

std::string Fmt(const std::optional<double>& v, int precision = 3) {
  if (!v) return "n/a";
  std::ostringstream os;
  os << std::fixed << std::setprecision(precision) << *v;
  return os.str();
}

}  // namespace

CameraIntrinsics ParseIntrinsicsFlag(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  bool ok = true;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      ok = ok && used == item.size();
    } catch (const std::logic_error&) {
      ok = false;
    }
  }
  if (!ok || v.size() != 4) {
    throw std::invalid_argument(
        fmt::format("--intrinsics expects fx,fy,cx,cy (4 numbers), got '{}'", text));
  }
  CameraIntrinsics c;
  c.fx = v[0];
  c.fy = v[1];
  c.cx = v[2];
  c.cy = v[3];
  // "intrinsics: fx must be positive ..." -> "--intrinsics: fx must be positive ...".
  CheckNamingFlags({{"intrinsics", "--intrinsics"}}, [&] { c.Check(); });
  return c;
}

void AddDetectorOverrideFlags(CLI::App& app, DetectorOverrides* o) {
  const LoopDetector::Options defaults;
  app.add_option("-K,--features", o->k,
                 "Informative features kept per keyframe (overrides --config)")
      ->check(IntegerAtLeast(1))
      ->default_str(std::to_string(defaults.features.max_features));
  app.add_option("--search", o->search,
                 "Search area: paper | radius | global (overrides --config; global without poses)")
      ->check(CLI::IsMember({"paper", "radius", "global"}))
      ->default_str(ToString(defaults.search.strategy));
  app.add_option("--exclude-recent", o->exclude_recent,
                 "Keyframes just before the query never searched (detector.search.exclude_recent; "
                 "a short sequence needs a small value)")
      ->check(IntegerAtLeast(0))
      ->default_str(std::to_string(defaults.search.exclude_recent));
  app.add_option("--min-path-ratio", o->min_path_ratio,
                 "A candidate needs a path from it to the query of at least this many times "
                 "their straight-line distance (detector.min_path_ratio; needs poses; 0: off)")
      ->default_str(fmt::format("{}", defaults.min_path_ratio));
  app.add_option("--set", o->set,
                 "KEY=VALUE: any configuration key (after --config and the flags above; "
                 "repeatable; `sparseloop config --dump` lists the keys), e.g. --set "
                 "detector.features.max_features=15 --set optimizer.rejection=pcm");
}

void ApplyDetectorOverrides(const DetectorOverrides& o, LoopDetector::Options* options) {
  if (o.k) options->features.max_features = *o.k;
  if (!o.search.empty()) options->search.strategy = ParseSearchStrategy(o.search);
  if (o.exclude_recent) options->search.exclude_recent = *o.exclude_recent;
  if (o.min_path_ratio) options->min_path_ratio = *o.min_path_ratio;
  CheckNamingFlags({{"features.max_features (K)", "-K"},
                    {"exclude_recent", "--exclude-recent"},
                    {"min_path_ratio", "--min-path-ratio"}},
                   [&] { options->Check(); });
}

void AddDetectorFlags(CLI::App& app, DetectorFlags* f) {
  app.add_option("--dataset", f->dataset,
                 "kitti:DIR | tum:DIR | euroc:DIR | images:DIR | "
                 "rosbag:FILE.bag?image=TOPIC[&pose=TOPIC&camera_info=TOPIC&gt=TOPIC]")
      ->required();
  app.add_option("--poses", f->poses,
                 "Raw vSLAM poses (TUM, KITTI, EuRoC or positions file); required unless the "
                 "rosbag: dataset names a pose=TOPIC");
  app.add_option("--intrinsics", f->intrinsics, "fx,fy,cx,cy (required for images:DIR)");
  AddDetectorOverrideFlags(app, &f->detector);
  app.add_option("--preset", f->preset,
                 fmt::format("A shipped configuration, applied before --config: {} "
                             "(docs/FORMATS.md, Presets)",
                             fmt::join(PresetNames(), " | ")));
  app.add_option("--config", f->config, "JSON configuration (see docs/FORMATS.md)");
  app.add_option("--out", f->out, "Output directory")->required();
  app.add_flag("--quiet", f->quiet, "No progress line");
}

std::optional<Trajectory> RawPosesForFrames(const std::string& poses_flag, const Dataset& dataset,
                                            double max_dt) {
  Trajectory raw_file;
  std::string source = poses_flag;
  if (!poses_flag.empty()) {
    raw_file = ReadTrajectory(poses_flag);
    RequireOrientations("--poses", poses_flag, raw_file);
  } else if (!dataset.raw_poses.empty()) {
    raw_file = dataset.raw_poses;
    source = dataset.raw_poses_source;
  } else {
    return std::nullopt;
  }
  return MatchRawPosesToFrames(dataset, raw_file, max_dt, source);
}

bool DatasetHasPoseTopic(const std::string& dataset_spec) {
  return IsRosbagSpec(dataset_spec) && !ParseRosbagSpec(dataset_spec).pose.empty();
}

void ApplySetFlags(const std::vector<std::string>& set, PipelineOptions* options) {
  for (const std::string& arg : set) {
    const size_t eq = arg.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw std::invalid_argument(fmt::format(
          "--set {}: expected KEY=VALUE (e.g. detector.features.max_features=15)", arg));
    }
    try {
      ApplyConfigOverride(arg.substr(0, eq), arg.substr(eq + 1), options);
      options->Check();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(fmt::format("--set {}: {}", arg, e.what()));
    }
  }
}

PipelineOptions PipelineOptionsFromFlags(const DetectorFlags& flags) {
  PipelineOptions options;
  if (flags.preset) {  // given, even empty: an empty value is an error, not the defaults
    try {
      ApplyPreset(*flags.preset, &options);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(fmt::format("--preset {}: {}", *flags.preset, e.what()));
    }
  }
  if (!flags.config.empty()) LoadConfigFile(flags.config, &options);
  ApplyDetectorOverrides(flags.detector, &options.detector);
  ApplySetFlags(flags.detector.set, &options);
  if (flags.poses.empty() && !DatasetHasPoseTopic(flags.dataset) &&
      options.detector.search.strategy != SearchStrategy::kGlobal) {
    // Without poses only the global search is defined.
    options.detector.search.strategy = SearchStrategy::kGlobal;
  }
  options.Check();
  return options;
}

Dataset OpenDatasetFromFlags(const DetectorFlags& flags) {
  DatasetOptions options;
  options.intrinsics_name = "--intrinsics";
  if (!flags.intrinsics.empty()) options.intrinsics = ParseIntrinsicsFlag(flags.intrinsics);
  return OpenDatasetSpec(flags.dataset, options);
}

std::invalid_argument NotAnEarlierOutput(const std::string& out, const std::string& command,
                                         const std::string& what) {
  return std::invalid_argument(fmt::format(
      "--out {}: expected an empty folder or the output of an earlier `sparseloop {}`, got {}; "
      "choose another --out",
      out, command, what));
}

std::string OtherEntries(std::vector<std::string> entries) {
  std::sort(entries.begin(), entries.end());
  return fmt::format("a folder holding {} other entr{} ({}{})", entries.size(),
                     entries.size() == 1 ? "y" : "ies", entries.empty() ? "" : entries.front(),
                     entries.size() > 1 ? ", ..." : "");
}

void PrepareRunFolder(const std::string& out, const std::string& command,
                      const std::string& dataset_spec, const std::vector<std::string>& files,
                      const std::vector<std::string>& inputs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const size_t colon = dataset_spec.find(':');
  if (colon != std::string::npos) {
    const fs::path dataset_dir = fs::weakly_canonical(dataset_spec.substr(colon + 1), ec);
    if (!ec && ResolvedPath(out) == dataset_dir) {
      throw std::invalid_argument(fmt::format(
          "--out {}: expected a folder other than the dataset's ({}): the next run would read "
          "the outputs written there as its input",
          out, dataset_spec));
    }
  }
  // `DIR/missing/..` is DIR: the folder the files will be written to is the one checked.
  const fs::path dir = ResolvedPath(out);
  if (!fs::is_directory(dir, ec)) return;  // created later; CheckOutputDirFlag checked it
  const auto is_own = [&](const std::string& name) {
    return std::find(files.begin(), files.end(), name) != files.end() || name == "report.html" ||
           (name.rfind("report_", 0) == 0 && fs::path(name).extension() == ".png");
  };
  const auto is_input = [&](const fs::path& path) {
    for (const std::string& input : inputs) {
      if (input.empty()) continue;
      // A --map database comes with SQLite's -wal / -shm files.
      for (const char* suffix : {"", "-wal", "-shm"}) {
        std::error_code e;
        if (fs::equivalent(path, input + suffix, e)) return true;
      }
    }
    return false;
  };
  std::vector<std::string> entries, foreign;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (is_input(entry.path())) continue;  // an input of this run: neither foreign nor removed
    entries.push_back(name);
    if (!is_own(name) || !entry.is_regular_file()) foreign.push_back(name);
  }
  if (entries.empty()) return;
  bool same_command = false;
  try {
    std::ifstream in(dir / "summary.json");
    if (in) same_command = nlohmann::json::parse(in).value("command", "") == command;
  } catch (const std::exception&) {
    same_command = false;
  }
  if (!same_command && !foreign.empty())
    throw NotAnEarlierOutput(out, command, OtherEntries(foreign));
  std::vector<std::string> removed;
  std::sort(entries.begin(), entries.end());
  for (const std::string& name : entries) {
    if (is_own(name) && fs::remove(dir / name, ec)) removed.push_back(name);
  }
  if (!removed.empty()) {
    Logger().info(
        "--out {}: removed {} file{} of the previous `{}` ({}), so the folder holds "
        "this run only",
        out, removed.size(), removed.size() == 1 ? "" : "s", command, fmt::join(removed, ", "));
  }
}

void RequireOrientations(const std::string& flag, const std::string& path, const Trajectory& t) {
  if (t.has_rotation) return;
  throw std::invalid_argument(fmt::format(
      "{} {}: expected a trajectory with orientations (TUM, KITTI or EuRoC), got a "
      "positions-only file (frame x y z): `run` needs every pose's rotation for the pose graph "
      "and its evaluation (`sparseloop eval` scores positions-only trajectories)",
      flag, path));
}

ProgressLine::ProgressLine(std::string label, bool quiet)
    : label_(std::move(label)), enabled_(!quiet && isatty(STDERR_FILENO)), start_s_(NowSeconds()) {}

void ProgressLine::Update(size_t done, size_t total, size_t loops) {
  if (!enabled_) return;
  const double now = NowSeconds();
  if (done != total && now - last_s_ < 0.2) return;
  last_s_ = now;
  const double rate = done / std::max(now - start_s_, 1e-9);
  const double eta = rate > 0 ? (total - done) / rate : 0.0;
  std::fprintf(stderr, "\r%s: %zu/%zu frames (%.0f%%)  %.1f frames/s  %zu loops  eta %.0f s   ",
               label_.c_str(), done, total, total ? 100.0 * done / total : 100.0, rate, loops, eta);
  std::fflush(stderr);
}

void ProgressLine::Finish() {
  if (enabled_) std::fprintf(stderr, "\n");
}

ImageNames ImageNamesByFrame(const Dataset& dataset) {
  ImageNames names;
  for (const DatasetFrame& f : dataset.frames) names[f.index] = f.image_path.filename().string();
  return names;
}

// `text` as one CSV field (RFC 4180): quoted, with its quotes doubled, when it holds a comma, a
// quote or a line end (an image named "a,b.png" must not add a column for `eval --loops`).
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string ImageColumns(const LoopResult& loop, const ImageNames& images) {
  const auto name = [&](int64_t frame) {
    const auto it = images.find(frame);
    return it == images.end() ? std::string() : CsvField(it->second);
  };
  return "," + name(loop.query_id) + "," + (loop.match_session == 0 ? name(loop.match_id) : "");
}

void WriteFramesCsv(const std::filesystem::path& path, const std::vector<LoopResult>& results) {
  WriteFileAtomically(path, [&](std::ostream& os) {
    os << "frame,status,candidates,matches,inliers,match,source,verified_area,"
          "verified_appearance,appearance_candidates,pose_segment,pose_reset,area\n";
    const auto ids = [](const std::vector<int64_t>& v) {
      return fmt::format("{}", fmt::join(v, ";"));
    };
    for (const LoopResult& r : results) {
      os << r.query_id << ',' << ToString(r.status) << ',' << r.candidates << ',' << r.matches
         << ',' << r.inliers << ',' << r.match_id << ',' << (r.detected() ? ToString(r.source) : "")
         << ',' << ids(r.verified_in_area) << ',' << ids(r.verified_by_appearance) << ','
         << r.appearance_candidates << ',' << r.pose_segment << ',' << ToString(r.pose_reset) << ','
         << FormatIdRanges(r.area) << '\n';
    }
  });
}

nlohmann::json StatusCountsJson(const std::vector<LoopResult>& results) {
  std::map<std::string, int> counts;
  for (LoopStatus s :
       {LoopStatus::kDetected, LoopStatus::kSkipped, LoopStatus::kNoFeatures,
        LoopStatus::kNoCandidates, LoopStatus::kTooFewMatches, LoopStatus::kTooFewInliers,
        LoopStatus::kRejectedByConsistency, LoopStatus::kRejectedByTemporal}) {
    counts[ToString(s)] = 0;
  }
  for (const auto& r : results) counts[ToString(r.status)]++;
  return counts;
}

nlohmann::json SourceCountsJson(const std::vector<LoopResult>& results) {
  std::map<std::string, int> counts;
  for (CandidateSource s : {CandidateSource::kSearchArea, CandidateSource::kAppearance,
                            CandidateSource::kEarlierSegment})
    counts[ToString(s)] = 0;
  for (const auto& r : results)
    if (r.detected()) counts[ToString(r.source)]++;
  return counts;
}

void WriteLoopsCsv(const std::filesystem::path& path, const std::vector<LoopResult>& loops,
                   const std::vector<bool>* accepted, const LoopTruth* truth,
                   const ImageNames& images, bool graph_columns) {
  WriteFileAtomically(path, [&](std::ostream& os) {
    os << "query,match,score,inliers,status,pose_kind,planar_alternative,"
       << (graph_columns ? "accepted,correct," : "")
       << "qx,qy,qz,qw,tx,ty,tz,scale,match_session,query_image,match_image,method,"
          "local_poses_from_images,local_poses_raw\n";
    os << std::setprecision(10);
    for (size_t i = 0; i < loops.size(); ++i) {
      const LoopResult& l = loops[i];
      const auto& q = l.match_from_query.rotation;
      const auto& t = l.match_from_query.translation;
      os << l.query_id << ',' << l.match_id << ',' << l.score << ',' << l.inliers << ','
         << ToString(l.status) << ',' << ToString(l.pose_kind) << ','
         << (l.planar_alternative ? 1 : 0) << ',';
      if (graph_columns) {
        if (accepted && i < accepted->size()) os << ((*accepted)[i] ? 1 : 0);
        os << ',';
        if (truth && i < truth->correct.size() && truth->correct[i])
          os << (*truth->correct[i] ? 1 : 0);
        os << ',';
      }
      os << q.x() << ',' << q.y() << ',' << q.z() << ',' << q.w() << ',' << t.x() << ',' << t.y()
         << ',' << t.z() << ',' << l.match_from_query.scale << ',' << l.match_session
         << ImageColumns(l, images) << ',' << ToString(l.method) << ',' << l.local_poses_from_images
         << ',' << l.local_poses_raw << '\n';
    }
  });
}

void WriteTimingsCsv(const std::filesystem::path& path, const std::vector<LoopResult>& results) {
  WriteFileAtomically(path, [&](std::ostream& os) {
    os << "keyframe,status,extract_ms,search_ms,match_ms,verify_ms,total_ms\n";
    os << std::setprecision(6);
    for (const LoopResult& r : results) {
      os << r.query_id << ',' << ToString(r.status) << ',' << r.timings.extract_ms << ','
         << r.timings.search_ms << ',' << r.timings.match_ms << ',' << r.timings.verify_ms << ','
         << r.timings.total_ms << '\n';
    }
  });
}

void WritePrCurveCsv(const std::filesystem::path& path, const LoopPrResult& pr) {
  WriteFileAtomically(path, [&](std::ostream& os) {
    os << "threshold,precision,recall\n" << std::setprecision(8);
    for (const LoopPrPoint& p : pr.curve) {
      os << p.threshold << ',' << p.precision << ',' << p.recall << '\n';
    }
  });
}

nlohmann::json DetectionSummaryJson(const PipelineResult& result, size_t loops) {
  const std::vector<LoopResult>& results = result.frame_results;
  nlohmann::json j;
  j["keyframes"] = results.size();
  j["loops"] = loops;
  j["bytes_per_keyframe"] = result.bytes_per_keyframe;
  j["status_counts"] = StatusCountsJson(results);
  j["loop_sources"] = SourceCountsJson(results);
  j["mapped_pixels"] = {{"keyframes", result.mapped_keyframes},
                        {"keyframes_without_depth", result.mapped_keyframes_without_depth}};
  // Raw pose resets (the caller's, or jumps the detector noticed): frame and reason.
  j["pose_resets"] = nlohmann::json::array();
  for (const auto& r : results)
    if (r.pose_reset != PoseReset::kNone)
      j["pose_resets"].push_back({{"frame", r.query_id}, {"reason", ToString(r.pose_reset)}});
  std::map<std::string, std::vector<double>> stages;
  for (const auto& r : results) {
    stages["extract"].push_back(r.timings.extract_ms);
    stages["search"].push_back(r.timings.search_ms);
    stages["match"].push_back(r.timings.match_ms);
    stages["verify"].push_back(r.timings.verify_ms);
    stages["total"].push_back(r.timings.total_ms);
  }
  for (auto& [name, values] : stages) {
    const Stats s = ComputeStats(values);
    j["timing_ms"][name] = {
        {"median", s.median}, {"p90", s.p90}, {"p99", s.p99}, {"max", s.max}, {"mean", s.mean}};
  }
  return j;
}

void AddLoopTruthJson(nlohmann::json& summary, const LoopTruth& truth,
                      const std::vector<bool>& accepted) {
  size_t known = 0, acc_correct = 0, acc_false = 0;
  for (size_t i = 0; i < truth.correct.size(); ++i) {
    if (!truth.correct[i]) continue;
    ++known;
    if (i < accepted.size() && accepted[i]) (*truth.correct[i] ? acc_correct : acc_false)++;
  }
  if (known == 0 && truth.correct.empty() && truth.threshold == 0.0) return;
  summary["loops_correct"] = truth.num_correct();
  summary["loops_false"] = truth.num_false();
  summary["accepted_loops_correct"] = acc_correct;
  summary["accepted_loops_false"] = acc_false;
  summary["gt_loop_distance"] = truth.threshold;
}

void PrintRunSummary(std::ostream& os, const nlohmann::json& s, const TrajectoryEvaluation* raw,
                     const TrajectoryEvaluation* corrected) {
  os << "sparseloop run summary\n";
  os << "  keyframes            " << s.value("keyframes", 0) << "\n";
  os << "  loops found          " << s.value("loops", 0)
     << "  (accepted by the pose graph: " << s.value("accepted_loops", 0) << ")\n";
  if (s.contains("loops_correct")) {
    os << "  loops correct/false  " << s["loops_correct"] << " / " << s["loops_false"]
       << "  (GT distance < " << std::setprecision(3) << s["gt_loop_distance"].get<double>()
       << ")\n";
    os << "  accepted correct/false " << s["accepted_loops_correct"] << " / "
       << s["accepted_loops_false"] << "  (after outlier rejection)\n";
  }
  os << std::fixed << std::setprecision(2);
  os << "  ms per keyframe      median " << s["timing_ms"]["total"]["median"].get<double>()
     << ", p90 " << s["timing_ms"]["total"]["p90"].get<double>() << "\n";
  os << "  bytes per keyframe   " << std::setprecision(0) << s.value("bytes_per_keyframe", 0.0)
     << "\n";
  if (s.contains("optimizer")) {
    os << std::setprecision(4) << "  optimizer            "
       << s["optimizer"]["status"].get<std::string>() << ", cost "
       << s["optimizer"]["initial_cost"].get<double>() << " -> "
       << s["optimizer"]["final_cost"].get<double>() << ", "
       << s["optimizer"]["iterations"].get<int>() << " iterations\n";
  }
  if (raw && corrected) {
    os << "  metric                         raw      corrected\n";
    auto row = [&](const char* name, std::optional<double> a, std::optional<double> b) {
      os << "  " << std::left << std::setw(28) << name << std::right << std::setw(9) << Fmt(a)
         << "  " << std::setw(9) << Fmt(b) << "\n";
    };
    row("ATE rmse (sim3-aligned)", raw->ate.rmse, corrected->ate.rmse);
    row("ATE max", raw->ate.max, corrected->ate.max);
    if (raw->kitti && corrected->kitti) {
      row("KITTI t_err (%)", raw->kitti->t_err_pct, corrected->kitti->t_err_pct);
      row("KITTI r_err (deg/100 m)", raw->kitti->r_err_deg_per_100m,
          corrected->kitti->r_err_deg_per_100m);
    }
  }
}

}  // namespace sparseloop::cli
