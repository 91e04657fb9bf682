#pragma once
// The ROS node's logic without ROS (sparseloop_node, docs/ROS.md): image / pose / mapped-point
// messages in (the plain structs of bag/bag_messages.h), synchronised by stamp in bounded queues,
// keyframes into runtime::LoopClosing on a worker thread, loop events and corrected trajectories
// out through callbacks as plain structs. node_main.cc (C++17, the only file with roscpp) turns ROS
// messages into these structs and these structs into ROS messages; this header is std-only so that
// both sides include it.
//
// Synchronisation. Every image is a keyframe candidate (subscribe the vSLAM's keyframe images). An
// image takes the raw pose whose stamp is nearest within max_pose_dt. It waits in a queue ordered
// by stamp until that pose has come (a pose stamped at or after image + max_pose_dt has arrived, so
// no nearer one can), or until the queue holds more than image_queue images (the oldest then goes
// on without a pose: tracking lost, the detector relocalises it), or Finish. Images stamped at or
// before the last processed one (out of order, duplicates) are dropped and counted; poses may come
// in any order. Images wait for the first camera_info (dropped, counted, if the queue fills first).
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bag/bag_messages.h"

namespace sparseloop::ros_node {

// The node's own parameters (the pipeline's are the config keys, in `config_json`).
struct NodeParams {
  // A shipped preset (~preset: PresetNames(); applied first), the `--config` keys as a JSON
  // object (the node's ~config parameter) and/or a JSON file (~config_file; applied after the
  // preset, then config_json on top). Empty: defaults.
  std::string preset;
  std::string config_json;
  std::string config_file;
  // true: the pose graph is solved in the background while keyframes come (a correction after
  // each loop); false: once, in Finish (what `sparseloop run` computes).
  bool solve_while_running = true;
  double max_pose_dt = 0.01;  // s: largest |image stamp - pose stamp| of a matched pose (> 0)
  int image_queue = 64;       // images waiting for their pose (>= 1)
  int pose_buffer = 10000;    // raw poses kept for matching (>= 1); the oldest go first
  // Mapped points (PointCloud2 in the camera frame) are attached to the image of the same stamp
  // (within max_pose_dt); with wait_for_points an image also waits for its points, as for its pose.
  bool wait_for_points = false;
  // Written by Finish when non-empty: the corrected keyframe trajectory (TUM: stamp x y z qx qy qz
  // qw, what evo reads) and loops.csv (query_stamp,match_stamp,query,match,inliers,score,pose_kind,
  // in_graph,accepted).
  std::string trajectory_file;
  std::string loops_file;
  // Throws std::invalid_argument naming the parameter.
  void Check() const;
};

// One detected loop (LoopResult of a keyframe with status "detected").
struct LoopMessage {
  double query_stamp = 0.0;
  double match_stamp = 0.0;
  int64_t query_id = 0;  // keyframe ids: 0, 1, ... in processing order
  int64_t match_id = 0;
  // p_in_match = match_from_query * p_in_query: translation, rotation x y z w, scale.
  std::array<double, 3> translation = {0, 0, 0};
  std::array<double, 4> rotation_xyzw = {0, 0, 0, 1};
  double scale = 1.0;
  int inliers = 0;
  double score = 0.0;
  std::string pose_kind;  // "none", "se3_unit_translation", "se3_metric", "sim3"
  bool in_graph = false;  // sent to the pose graph as a loop edge
};

// Corrected poses of every keyframe with a raw pose, after a solve (or Finish).
struct PathMessage {
  uint64_t revision = 0;  // the solve (0: raw poses, no solve yet)
  std::vector<double> stamps;
  std::vector<std::array<double, 3>> positions;       // world frame of the raw poses
  std::vector<std::array<double, 4>> rotations_xyzw;  // camera-to-world
  std::vector<double> scales;                         // Sim(3) scale of each keyframe's correction
  // Loops in the graph that the solve kept (PCM), as indices into `stamps` (query, match).
  std::vector<std::array<size_t, 2>> loops;
};

// The covariance of the raw step from the previous keyframe to this one, [translation(3),
// rotation(3)] in the previous keyframe's frame (KeyframeInput::odometry_covariance), from the
// covariances of the two absolute poses as a ROS PoseWithCovariance / Odometry gives them (world
// frame, fixed axes): a vSLAM's absolute uncertainty grows by the uncertainty of each step, so the
// step's is the growth, Sigma_k - Sigma_prev, rotated into the previous keyframe's frame (both
// blocks by R_prev^T; first order, the lever-arm coupling of rotation into translation left out).
// nullopt when the growth is not positive definite (eigenvalue <= 1e-12 x its largest: a reset,
// a constant or a shrinking covariance), or either covariance is all zero (none given).
std::optional<std::array<double, 36>> StepCovarianceFromAbsolute(
    const std::array<double, 4>& prev_rotation_xyzw, const std::array<double, 36>& prev_covariance,
    const std::array<double, 36>& covariance);

struct NodeStats {
  int64_t images = 0;                  // image messages received
  int64_t keyframes = 0;               // processed (LoopClosing::AddKeyframe)
  int64_t keyframes_without_pose = 0;  // of those, with no pose within max_pose_dt
  int64_t keyframes_with_points = 0;   // of those, with mapped points
  // Of those, with the step covariance from the pose messages' (StepCovarianceFromAbsolute), and
  // with pose covariances whose growth was not usable (the default odometry model then).
  int64_t keyframes_with_covariance = 0;
  int64_t covariance_unusable = 0;
  int64_t poses = 0;                   // pose messages received
  int64_t dropped_out_of_order = 0;    // images stamped at or before the last processed one
  int64_t dropped_no_camera_info = 0;  // images pushed out of the queue before camera_info came
  int64_t dropped_bad = 0;        // images / poses / points that did not convert (see warnings)
  int64_t loops = 0;              // detected loops
  int64_t solves = 0;             // pose-graph solves completed
  int64_t queued = 0;             // images waiting now
  double mean_keyframe_ms = 0.0;  // AddKeyframe wall time, mean
  // Every counter by name (the finish summary and /diagnostics).
  std::vector<std::pair<std::string, double>> Fields() const;
};

struct NodeCallbacks {
  // Each on the worker or the optimiser's thread; they must not call back into NodeCore.
  std::function<void(const LoopMessage&)> on_loop;
  std::function<void(const PathMessage&)> on_path;  // after each solve and at Finish
  std::function<void(const std::string&)> on_warning;
};

class NodeCore {
 public:
  // Throws std::invalid_argument (bad parameters or config keys; the message names them).
  NodeCore(const NodeParams& params, NodeCallbacks callbacks);
  ~NodeCore();  // Finish()
  NodeCore(const NodeCore&) = delete;
  NodeCore& operator=(const NodeCore&) = delete;

  // From any thread (ROS callbacks); they queue and return.
  void AddCameraInfo(const bag_internal::CameraInfoMessage& info);
  void AddImage(bag_internal::ImageData image);
  void AddPose(const bag_internal::PoseMessage& pose);
  // Points in the camera frame (x y z per point, the raw poses' units), stamped like their image.
  void AddMappedPoints(double stamp, std::vector<double> xyz);

  // Processes every queued image (those without a pose go on without one), runs the final solve,
  // delivers the final path, writes the files of NodeParams. Returns a JSON summary (stats,
  // accepted loops). Idempotent (later calls return the same summary).
  std::string Finish();
  NodeStats Stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sparseloop::ros_node
