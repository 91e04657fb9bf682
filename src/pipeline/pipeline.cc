#include "sparseloop/pipeline/pipeline.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/time_association.h"
#include "sparseloop/core/timer.h"
#include "sparseloop/io/mapped_pixels.h"
#include "sparseloop/map/map_database.h"
#include "sparseloop/pipeline/dataset_source.h"
#include "sparseloop/pipeline/map_records.h"
#include "sparseloop/posegraph/interpolation.h"

namespace sparseloop {

namespace {
constexpr int kMaxThreads = 256;
}  // namespace

void PipelineOptions::Check() const {
  detector.Check();
  optimizer.Check();
  // Threads started per solve / per index query: beyond this a value only costs (Ceres warns
  // through glog, which then prints "Logging before InitGoogleLogging()").
  SL_CHECK_MSG(optimizer.num_threads <= kMaxThreads, "num_threads must be in [1, {}], got {}",
               kMaxThreads, optimizer.num_threads);
  SL_CHECK_MSG(detector.ann.num_threads <= kMaxThreads,
               "ann.num_threads must be in [1, {}], got {}", kMaxThreads, detector.ann.num_threads);
  odometry.Check();
  LoopEdgeOptions::Check();
  SL_CHECK_MSG(raw_association_max_dt > 0, "raw_association_max_dt must be > 0");
}

namespace {

// The one association of per-frame inputs (raw poses, step covariances) with the dataset's frames:
// by time (core's rule, TimePairing::kNearest: the key nearest the frame's timestamp within
// max_dt) when the input has timestamps and the dataset is not index-associated (KITTI, images:),
// else by frame index (key == frame). Returns the input row of each frame, or nothing where no row
// is close enough.
bool AssociateByTime(const Dataset& dataset, bool input_has_timestamps) {
  return input_has_timestamps && dataset.kind != "kitti" && dataset.kind != "images";
}

std::vector<std::optional<size_t>> RowsForFrames(const Dataset& dataset,
                                                 const std::vector<double>& keys, bool by_time,
                                                 double max_dt) {
  if (!by_time) {
    std::unordered_map<int64_t, size_t> by_frame;
    for (size_t i = 0; i < keys.size(); ++i) by_frame[static_cast<int64_t>(keys[i])] = i;
    std::vector<std::optional<size_t>> rows;
    rows.reserve(dataset.frames.size());
    for (const auto& f : dataset.frames) {
      const auto it = by_frame.find(f.index);
      rows.push_back(it == by_frame.end() ? std::nullopt : std::optional<size_t>(it->second));
    }
    return rows;
  }
  std::vector<double> frame_times;
  for (const auto& f : dataset.frames) frame_times.push_back(f.timestamp);
  return AssociateInTime(frame_times, keys, max_dt, TimePairing::kNearest);
}

}  // namespace

Trajectory MatchRawPosesToFrames(const Dataset& dataset, const Trajectory& raw, double max_dt,
                                 const std::filesystem::path& raw_path) {
  Trajectory out;
  out.has_rotation = raw.has_rotation;
  out.has_timestamps = raw.has_timestamps;
  const bool by_time = AssociateByTime(dataset, raw.has_timestamps);
  std::vector<double> keys;
  for (const auto& p : raw.poses) {
    keys.push_back(by_time ? p.timestamp : static_cast<double>(p.frame));
  }
  const auto rows = RowsForFrames(dataset, keys, by_time, max_dt);
  for (size_t i = 0; i < dataset.frames.size(); ++i) {
    const DatasetFrame& f = dataset.frames[i];
    if (!rows[i]) {
      if (!by_time) {
        throw FileError(raw_path.string(), 0,
                        fmt::format("a raw pose for every image ({} images, frame {} has none)",
                                    dataset.frames.size(), f.index),
                        fmt::format("{} poses", raw.poses.size()));
      }
      throw FileError(raw_path.string(), 0,
                      fmt::format("a raw pose within {} s of every image timestamp", max_dt),
                      fmt::format("none for image {} at t={:.6f}", f.index, f.timestamp));
    }
    StampedPose p = raw.poses[*rows[i]];
    p.frame = f.index;
    if (!by_time) p.timestamp = f.timestamp;
    out.poses.push_back(p);
  }
  return out;
}

std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> MatchStepCovariancesToFrames(
    const Dataset& dataset, const std::vector<StepCovariance>& covariances, double max_dt) {
  // Keys are timestamps unless the dataset itself is index-associated.
  const bool by_time = AssociateByTime(dataset, true);
  std::vector<double> keys;
  for (const auto& c : covariances) keys.push_back(c.key);
  const auto rows = RowsForFrames(dataset, keys, by_time, max_dt);
  std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> out;
  bool any = false;
  for (const auto& row : rows) {
    out.push_back(row ? std::optional(covariances[*row].covariance) : std::nullopt);
    any |= row.has_value();
  }
  if (!any) {
    throw std::invalid_argument(
        fmt::format("no line matches a frame of the dataset (keys are {})",
                    by_time ? fmt::format("timestamps, within {} s", max_dt) : "frame indices"));
  }
  return out;
}

MappedPixels ReadMappedPixels(const std::filesystem::path& path) {
  MappedPixels out;
  for (const MappedPixelRow& row : ReadMappedPixelRows(path)) {
    out.pixels.emplace_back(row.u, row.v);
    out.depths.push_back(row.depth);
  }
  return out;
}

LoopClosing::Options LoopClosingOptionsFor(const PipelineOptions& options,
                                           bool solve_while_running) {
  LoopClosing::Options o;
  o.detector = options.detector;
  o.loop_edge = options;
  o.optimizer.solve = options.optimizer;
  o.optimizer.odometry = options.odometry;
  o.optimizer.vertex_type = options.vertex_type;
  o.optimizer.solve_while_running = solve_while_running;
  return o;
}

namespace {

using StepCovariances = std::vector<std::optional<Eigen::Matrix<double, 6, 6>>>;

// DIR/mapped/NNNNNN.txt: the mapped pixels of frame `index`.
std::filesystem::path MappedPixelsFile(const std::filesystem::path& mapped_dir, int64_t index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06lld.txt", static_cast<long long>(index));
  return mapped_dir / name;
}

// Frame i of the dataset as a keyframe: image (empty when unreadable), intrinsics, the raw pose
// and the caller's step covariance when given, the mapped pixels when `mapped_dir` has a file.
KeyframeInput FrameKeyframe(const Dataset& dataset, size_t i, const Trajectory* raw,
                            const StepCovariances& step_covariances,
                            const std::filesystem::path& mapped_dir) {
  const DatasetFrame& frame = dataset.frames[i];
  KeyframeInput input;
  input.id = frame.index;
  input.timestamp = frame.timestamp;
  input.image = ReadFrameGray(dataset, frame);
  if (input.image.empty()) return input;
  input.intrinsics = dataset.intrinsics;
  if (raw) input.world_from_cam = Sim3d(raw->poses[i].world_from_cam);
  if (!step_covariances.empty()) input.odometry_covariance = step_covariances[i];
  if (!mapped_dir.empty()) {
    const auto path = MappedPixelsFile(mapped_dir, frame.index);
    if (std::filesystem::exists(path)) {
      MappedPixels m = ReadMappedPixels(path);
      input.mapped_pixels = std::move(m.pixels);
      input.mapped_depths = std::move(m.depths);
    }
  }
  return input;
}

// Counts the keyframe's mapped pixels in `result`; a file holding only unknown depths (<= 0) is
// named in a warning (the first few; WarnMappedPixelsWithoutDepth sums up the rest).
void CountMappedPixels(const KeyframeInput& input, const std::filesystem::path& mapped_dir,
                       PipelineResult* result) {
  constexpr size_t kFilesNamed = 3;
  if (input.mapped_pixels.empty()) return;
  ++result->mapped_keyframes;
  if (std::any_of(input.mapped_depths.begin(), input.mapped_depths.end(),
                  [](float d) { return d > 0.0f; }))
    return;
  if (result->mapped_keyframes_without_depth++ < kFilesNamed) {
    Logger().warn("{}: {} mapped pixels, none with a positive depth (<= 0: unknown)",
                  MappedPixelsFile(mapped_dir, input.id).string(), input.mapped_pixels.size());
  }
}

void WarnMappedPixelsWithoutDepth(const std::filesystem::path& mapped_dir,
                                  const PipelineResult& result) {
  if (result.mapped_keyframes_without_depth == 0) return;
  Logger().warn(
      "{} of {} keyframes with mapped pixels ({}) have no positive depth: their features are "
      "taken around the mapped pixels, and their loops are verified without depths. If the "
      "vSLAM knows no depth, use_mapped_pixels=false extracts from the whole image",
      result.mapped_keyframes_without_depth, result.mapped_keyframes, mapped_dir.string());
}

// The run's session in the persistent map (options.map_path), earlier sessions loaded into
// `closing` first (options.load_map_sessions).
std::unique_ptr<MapDatabase> OpenMapSession(const Dataset& dataset, const PipelineOptions& options,
                                            LoopClosing* closing, PipelineResult* result) {
  if (options.map_path.empty()) return nullptr;
  auto map = MapDatabase::Open(options.map_path);
  if (options.load_map_sessions) {
    const float focal = static_cast<float>(0.5 * (dataset.intrinsics.fx + dataset.intrinsics.fy));
    result->prior_keyframes = LoadPriorSessions(*map, focal, closing);
  }
  result->map_session = map->BeginSession(options.session_label);
  return map;
}

// Loops of this run (accepted as the graph decided) and into earlier sessions (accepted = 0:
// not in the graph, their world frame differs).
void StoreLoops(const PipelineResult& result, MapDatabase* map) {
  const int64_t session = result.map_session;
  for (size_t k = 0; k < result.loops.size(); ++k) {
    const LoopResult& l = result.loops[k];
    map->PutLoop({session, l.query_id, session, l.match_id, l.inliers, l.score, l.match_from_query,
                  result.loop_accepted[k]});
  }
  for (const LoopResult& l : result.cross_session_loops) {
    map->PutLoop({session, l.query_id, l.match_session, l.match_id, l.inliers, l.score,
                  l.match_from_query, false});
  }
  map->Flush();
}

// Every frame's corrected pose: the graph keyframes from the solve (raw poses without one), the
// frames between them (skipped frames) through the interpolated correction.
Trajectory CorrectedTrajectory(const Trajectory& raw, const CorrectedKeyframes& keyframes,
                               const std::unordered_map<int64_t, size_t>& row_of_id) {
  if (keyframes.ids.empty()) return raw;  // every frame skipped
  std::vector<StampedSim3> raw_kf, corrected_kf, raw_all;
  for (size_t k = 0; k < keyframes.ids.size(); ++k) {
    const StampedPose& p = raw.poses[row_of_id.at(keyframes.ids[k])];
    raw_kf.push_back({p.timestamp, Sim3d(p.world_from_cam)});
    corrected_kf.push_back({p.timestamp, keyframes.world_from_keyframe[k]});
  }
  for (const auto& p : raw.poses) raw_all.push_back({p.timestamp, Sim3d(p.world_from_cam)});
  const auto corrected_all = CorrectFramePoses(raw_kf, corrected_kf, raw_all);
  Trajectory corrected = raw;
  for (size_t i = 0; i < raw.poses.size(); ++i) {
    corrected.poses[i].world_from_cam = corrected_all[i].world_from_cam.ToRigid();
  }
  return corrected;
}

// The graph's verdict on each loop of the run (loop_index: its index in the graph's loop list,
// -1 when it did not go to the graph) and the solve's summary.
void TakeSolve(const LoopClosing& closing, const std::vector<int64_t>& loop_index,
               PipelineResult* result) {
  const auto solve = closing.LatestSolve();
  if (solve) {
    result->optimizer = solve->summary;
  } else {
    result->optimizer.status = PoseGraphStatus::kNothingToDo;
    result->optimizer.num_vertices = closing.graph().num_vertices();
    result->optimizer.num_edges = closing.graph().edges().size();
  }
  std::vector<bool> rejected(closing.num_loops(), false);
  for (size_t idx : result->optimizer.rejected_loops) rejected.at(idx) = true;
  result->loop_accepted.assign(result->loops.size(), false);
  for (size_t k = 0; k < result->loops.size(); ++k) {
    result->loop_accepted[k] = loop_index[k] >= 0 && !rejected[static_cast<size_t>(loop_index[k])];
  }
}

// The one offline driver: `run` (optimize) and `detect` (not) over one LoopClosing.
PipelineResult RunOffline(const Dataset& dataset, const Trajectory* raw,
                          const StepCovariances& step_covariances, const PipelineOptions& options,
                          bool optimize, const PipelineProgressCallback& progress) {
  options.Check();
  SL_CHECK_MSG(raw != nullptr || !optimize, "the pose graph needs raw poses");
  SL_CHECK_MSG(raw == nullptr || raw->poses.size() == dataset.frames.size(),
               "raw trajectory has {} poses for {} frames; use MatchRawPosesToFrames",
               raw ? raw->poses.size() : 0, dataset.frames.size());
  SL_CHECK_MSG(step_covariances.empty() || step_covariances.size() == dataset.frames.size(),
               "{} step covariances for {} frames; use MatchStepCovariancesToFrames",
               step_covariances.size(), dataset.frames.size());
  PipelineResult result;
  if (raw) result.raw = *raw;
  LoopClosing::Options closing_options = LoopClosingOptionsFor(options, false);
  closing_options.optimize = optimize;
  LoopClosing closing(std::move(closing_options));
  std::unique_ptr<MapDatabase> map = OpenMapSession(dataset, options, &closing, &result);

  const auto mapped_dir = dataset.root / "mapped";
  const bool have_mapped = options.use_mapped_pixels && std::filesystem::is_directory(mapped_dir);
  std::unordered_map<int64_t, size_t> row_of_id;  // frame index -> row of the dataset / raw
  std::vector<int64_t> loop_index;                // per result.loops: index in the graph or -1
  bool first_in_graph = true;
  Timer detect_timer;
  for (size_t i = 0; i < dataset.frames.size(); ++i) {
    const DatasetFrame& frame = dataset.frames[i];
    const KeyframeInput input = FrameKeyframe(dataset, i, raw, step_covariances,
                                              have_mapped ? mapped_dir : std::filesystem::path());
    if (input.image.empty()) {
      const std::string problem = ImageReadProblem(frame.image_path);
      if (!options.skip_unreadable_frames) {
        throw FileError(frame.image_path.string(), 0, "a readable image", problem);
      }
      Logger().warn("skipping frame {}: cannot read image {}: {}", frame.index,
                    frame.image_path.string(), problem);
      ++result.skipped_frames;
      continue;
    }
    LoopEvent event = closing.AddKeyframe(input);
    CountMappedPixels(input, mapped_dir, &result);
    row_of_id[frame.index] = i;
    result.keyframe_frames.push_back(frame.index);
    if (event.in_graph) {
      if (!first_in_graph && input.odometry_covariance) ++result.caller_covariance_steps;
      first_in_graph = false;
    }
    const PackedKeyframe& stored = closing.detector().packed_record(frame.index);
    if (map) map->PutRecord(result.map_session, stored);
    LoopResult& r = event.result;
    if (r.detected() && r.match_session == 0) {
      result.loops.push_back(r);
      result.loop_information.push_back(event.loop_information);
      loop_index.push_back(event.loop_index);
    } else if (r.detected()) {
      result.cross_session_loops.push_back(r);
    }
    result.frame_results.push_back(std::move(r));
    if (progress) progress({i + 1, dataset.frames.size(), result.loops.size()});
  }
  result.detect_seconds = detect_timer.ElapsedMs() / 1000.0;
  WarnMappedPixelsWithoutDepth(mapped_dir, result);
  size_t bytes = 0;
  for (const auto& [id, row] : row_of_id) bytes += closing.detector().packed_record(id).Bytes();
  if (!row_of_id.empty()) result.bytes_per_keyframe = double(bytes) / row_of_id.size();
  closing.Finish();

  if (optimize) {
    TakeSolve(closing, loop_index, &result);
    result.corrected = CorrectedTrajectory(*raw, closing.Corrections(), row_of_id);
  } else {
    result.loop_accepted.assign(result.loops.size(), true);
    result.corrected = result.raw;
  }
  if (map) StoreLoops(result, map.get());
  return result;
}

}  // namespace

PipelineResult RunPipeline(const Dataset& dataset, const Trajectory& raw,
                           const PipelineOptions& options,
                           const PipelineProgressCallback& progress) {
  return RunOffline(dataset, &raw, {}, options, /*optimize=*/true, progress);
}

PipelineResult RunPipeline(const Dataset& dataset, const Trajectory& raw,
                           const StepCovariances& step_covariances, const PipelineOptions& options,
                           const PipelineProgressCallback& progress) {
  return RunOffline(dataset, &raw, step_covariances, options, /*optimize=*/true, progress);
}

PipelineResult RunDetection(const Dataset& dataset, const std::optional<Trajectory>& raw_matched,
                            const PipelineOptions& options,
                            const PipelineProgressCallback& progress) {
  return RunOffline(dataset, raw_matched ? &*raw_matched : nullptr, {}, options,
                    /*optimize=*/false, progress);
}

}  // namespace sparseloop
