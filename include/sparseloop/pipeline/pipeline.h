#pragma once
// The offline driver behind `sparseloop run` and `sparseloop detect`, on top of the online API:
// every dataset frame is a keyframe of one runtime::LoopClosing (solving once, at Finish), with
// its raw vSLAM pose when there is one. `run`: the detector finds loops, the pose graph over the
// raw poses plus the loop edges is optimised (outlier loops rejected), and every raw pose is
// corrected (keyframes by the solve, poses between keyframes by interpolation of the correction
// on Sim(3)). `detect`: the same detection with the optimiser off.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sparseloop/core/trajectory.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/io/step_covariance.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/posegraph/pose_graph.h"
#include "sparseloop/runtime/loop_closing.h"
#include "sparseloop/runtime/loop_edge.h"

namespace sparseloop {

// The loop-edge options (direction_loop, loop_*) are inherited: one definition with LoopClosing,
// and their configuration keys stay at the top level.
struct PipelineOptions : LoopEdgeOptions {
  LoopDetector::Options detector;
  PoseGraphOptions optimizer;
  OdometryWeighting odometry;                  // information of the raw odometry edges
  VertexType vertex_type = VertexType::kSim3;  // kSim3 for monocular raw poses
  // Read DIR/mapped/NNNNNN.txt ("u v depth" per line) when the dataset folder has it.
  bool use_mapped_pixels = true;
  // Raw poses are matched to frames by timestamp when both have timestamps (max |dt|, seconds),
  // else by frame index.
  double raw_association_max_dt = 0.02;
  // A frame whose image cannot be read is skipped (logged, counted) instead of aborting the run.
  bool skip_unreadable_frames = true;
  // Persistent map (optional): keyframe records and loops are stored there in a new session.
  std::filesystem::path map_path;
  // With map_path: the sessions already in the map are loaded into the detector first, so this
  // run also closes loops against them (PipelineResult::cross_session_loops).
  bool load_map_sessions = true;
  std::string session_label = "run";
  void Check() const;
};

struct PipelineProgress {
  size_t frames_done = 0;
  size_t frames_total = 0;
  size_t loops = 0;
};
using PipelineProgressCallback = std::function<void(const PipelineProgress&)>;

struct PipelineResult {
  std::vector<LoopResult> frame_results;  // one per processed keyframe, in order
  std::vector<LoopResult> loops;          // the detected loops (before outlier rejection)
  // Per entry of `loops`: kept by the pose graph (in the graph and not rejected by PCM); without
  // the optimiser (RunDetection) every loop, as nothing rejects it.
  std::vector<bool> loop_accepted;
  // Per entry of `loops`: the information its edge has in the graph (LoopEvent::loop_information;
  // zero when not in the graph).
  std::vector<Matrix7d> loop_information;
  // Loops whose match is a keyframe of an earlier map session (LoopResult::match_session > 0).
  // Not in the pose graph (their world frame differs); stored in the map with accepted = 0.
  std::vector<LoopResult> cross_session_loops;
  std::vector<int64_t> keyframe_frames;  // dataset frame index of each processed keyframe
  size_t skipped_frames = 0;             // unreadable images (see skip_unreadable_frames)
  // Keyframes that had mapped pixels (a non-empty DIR/mapped/NNNNNN.txt, use_mapped_pixels), and
  // of those the ones without a single positive depth (every depth <= 0: unknown). Such
  // keyframes take their features around the mapped pixels yet verify loops without depths; the
  // run logs a warning naming their files.
  size_t mapped_keyframes = 0;
  size_t mapped_keyframes_without_depth = 0;
  PoseGraphSummary optimizer;
  Trajectory raw;                      // raw poses matched to the dataset's frames
  Trajectory corrected;                // same frames, corrected
  double bytes_per_keyframe = 0.0;     // mean PackedKeyframe::Bytes() of the stored keyframes
  double detect_seconds = 0.0;         // wall time of the detection loop (image decode included)
  size_t caller_covariance_steps = 0;  // odometry edges weighted by the caller's covariance
  int64_t map_session = 0;             // with map_path: this run's session in the map
  size_t prior_keyframes = 0;          // with map_path: keyframes of earlier sessions loaded
};

// The online LoopClosing configured as `run` is (same detector, loop edges, odometry weighting,
// vertex type and solve options): the one mapping from the config keys to the online API, used by
// the Python module and the tests that compare LoopClosing with RunPipeline.
// solve_while_running false = one solve in Finish(), what `run` computes.
LoopClosing::Options LoopClosingOptionsFor(const PipelineOptions& options,
                                           bool solve_while_running);

// The raw trajectory matched to the dataset's frames (by timestamp or index, see options).
// Throws FileError when a frame has no raw pose (e.g. a pose file shorter than the image list).
Trajectory MatchRawPosesToFrames(const Dataset& dataset, const Trajectory& raw, double max_dt,
                                 const std::filesystem::path& raw_path);

// The caller's step covariances (ReadStepCovariances) matched to the dataset's frames with the
// raw poses' rule: by frame index for KITTI and images: datasets, else by timestamp (nearest
// within max_dt). A frame without a line gets nothing: its step keeps the odometry model. Throws
// std::invalid_argument saying which keys were expected when no line matches any frame.
std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> MatchStepCovariancesToFrames(
    const Dataset& dataset, const std::vector<StepCovariance>& covariances, double max_dt);

// Mapped pixels as written by `sparseloop render` (DIR/mapped/NNNNNN.txt, read by
// ReadMappedPixelRows: "u v depth" per line, depth <= 0 unknown). Throws FileError on a malformed
// file.
struct MappedPixels {
  std::vector<cv::Point2f> pixels;
  std::vector<float> depths;
};
MappedPixels ReadMappedPixels(const std::filesystem::path& path);

// Frames whose image cannot be read are skipped (options.skip_unreadable_frames) and get the
// interpolated correction. Throws std::invalid_argument on invalid options, FileError on an
// unreadable image (skip_unreadable_frames false) or mapped-pixels file.
PipelineResult RunPipeline(const Dataset& dataset, const Trajectory& raw_matched,
                           const PipelineOptions& options,
                           const PipelineProgressCallback& progress = {});
// With the caller's odometry covariances (MatchStepCovariancesToFrames; one entry per frame or
// empty): the odometry edge ending at a keyframe with one uses its inverse as information
// (OdometryWeighting::InformationFromCovariance) and PCM its variances. Throws
// std::invalid_argument naming the frame for a covariance that is not positive definite.
PipelineResult RunPipeline(
    const Dataset& dataset, const Trajectory& raw_matched,
    const std::vector<std::optional<Eigen::Matrix<double, 6, 6>>>& step_covariances,
    const PipelineOptions& options, const PipelineProgressCallback& progress = {});

// Detection only (`detect`): the driver of RunPipeline with the optimiser off. `raw_matched`
// (MatchRawPosesToFrames) may be empty: no raw poses, every keyframe is searched as the detector
// does without a pose (options.detector.search.strategy global). PipelineResult::corrected and
// ::raw are the raw poses (empty without), `optimizer` is empty, every loop counts as accepted.
PipelineResult RunDetection(const Dataset& dataset, const std::optional<Trajectory>& raw_matched,
                            const PipelineOptions& options,
                            const PipelineProgressCallback& progress = {});

// Loops against GT (LoopTruth, ClassifyLoopsByGtDistance): eval/loops.h.

// MakeLoopConstraint (the loop edge for a detected loop): runtime/loop_edge.h.

}  // namespace sparseloop
