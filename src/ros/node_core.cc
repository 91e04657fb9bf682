#include "ros/node_core.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include "bag/message_convert.h"
#include "sparseloop/core/covariance.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/time_association.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/output_paths.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/pipeline.h"
#include "sparseloop/runtime/loop_closing.h"

namespace sparseloop::ros_node {

using bag_internal::ImageData;
using bag_internal::MessageError;

std::vector<std::pair<std::string, double>> NodeStats::Fields() const {
  return {{"images", images},
          {"keyframes", keyframes},
          {"keyframes_without_pose", keyframes_without_pose},
          {"keyframes_with_points", keyframes_with_points},
          {"keyframes_with_covariance", keyframes_with_covariance},
          {"covariance_unusable", covariance_unusable},
          {"poses", poses},
          {"queued", queued},
          {"loops", loops},
          {"solves", solves},
          {"mean_keyframe_ms", mean_keyframe_ms},
          {"dropped_out_of_order", dropped_out_of_order},
          {"dropped_no_camera_info", dropped_no_camera_info},
          {"dropped_bad", dropped_bad}};
}

void NodeParams::Check() const {
  if (!(max_pose_dt > 0.0 && std::isfinite(max_pose_dt))) {
    throw std::invalid_argument(fmt::format("~max_pose_dt must be > 0 s, got {}", max_pose_dt));
  }
  if (image_queue < 1) {
    throw std::invalid_argument(fmt::format("~image_queue must be >= 1, got {}", image_queue));
  }
  if (pose_buffer < 1) {
    throw std::invalid_argument(fmt::format("~pose_buffer must be >= 1, got {}", pose_buffer));
  }
  // No input written over (and not both outputs in one file: the second would replace the first),
  // then the output files themselves: checked now, not at finish, when the session's work would
  // be lost.
  CheckOutputsAreNotInputs({{"~trajectory_file", trajectory_file}, {"~loops_file", loops_file}},
                           {{"~config_file", config_file}});
  CheckOutputsAreNotInputs({{"~loops_file", loops_file}}, {{"~trajectory_file", trajectory_file}});
  for (const auto& [name, path] :
       {std::pair<const char*, const std::string&>{"~trajectory_file", trajectory_file},
        {"~loops_file", loops_file}}) {
    if (path.empty()) continue;
    try {
      CheckOutputFile(path);
    } catch (const FileError& e) {
      throw std::invalid_argument(fmt::format("{} {}", name, e.what()));
    }
  }
}

namespace {

PipelineOptions PipelineOptionsFrom(const NodeParams& params) {
  PipelineOptions p;
  if (!params.preset.empty()) {
    try {
      ApplyPreset(params.preset, &p);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(fmt::format("~preset {}: {}", params.preset, e.what()));
    }
  }
  if (!params.config_file.empty()) LoadConfigFile(params.config_file, &p);
  if (!params.config_json.empty()) {
    CheckJsonNesting(params.config_json, "~config", false);
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(params.config_json);
    } catch (const nlohmann::json::exception& e) {
      throw std::invalid_argument(fmt::format("~config is not a JSON object: {}", e.what()));
    }
    if (!j.is_object()) {
      throw std::invalid_argument(
          fmt::format("~config must be a dictionary of config keys, got {}", j.dump()));
    }
    ApplyConfig(j, "~config", &p);
  }
  return p;
}

// The entry whose stamp `stamp` takes within `max_dt`, if any: core's NearestInTime rule, on the
// map's own O(log n) search.
template <typename T>
std::optional<T> Nearest(const std::map<double, T>& by_stamp, double stamp, double max_dt) {
  const auto it = NearestInTime(by_stamp.begin(), by_stamp.lower_bound(stamp), by_stamp.end(),
                                stamp, max_dt, [](const auto& entry) { return entry.first; });
  if (it == by_stamp.end()) return std::nullopt;
  return it->second;
}

// A raw pose and its message's covariance (all zero: none).
struct PoseEntry {
  Rigid3d pose;
  std::array<double, 36> covariance{};
};

bool AllZero(const std::array<double, 36>& c) {
  return std::all_of(c.begin(), c.end(), [](double v) { return v == 0.0; });
}

struct LoopRecord {
  LoopMessage message;
  int64_t loop_index = -1;  // LoopEvent::loop_index
};

// Whether a solve over the first `num_loops` loops of the graph kept the loop (PCM).
bool Kept(const LoopRecord& l, size_t num_loops, const std::vector<size_t>& rejected) {
  return l.loop_index >= 0 && static_cast<size_t>(l.loop_index) < num_loops &&
         std::find(rejected.begin(), rejected.end(), static_cast<size_t>(l.loop_index)) ==
             rejected.end();
}

}  // namespace

std::optional<std::array<double, 36>> StepCovarianceFromAbsolute(
    const std::array<double, 4>& prev_rotation_xyzw, const std::array<double, 36>& prev_covariance,
    const std::array<double, 36>& covariance) {
  using Matrix6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;
  if (AllZero(prev_covariance) || AllZero(covariance)) return std::nullopt;
  const Matrix6 prev(prev_covariance.data());
  const Matrix6 now(covariance.data());
  if (!prev.allFinite() || !now.allFinite()) return std::nullopt;
  Matrix6 growth = now - prev;
  growth = 0.5 * (growth + growth.transpose()).eval();
  const Eigen::SelfAdjointEigenSolver<Matrix6> eig(growth);
  const double largest = eig.eigenvalues().maxCoeff();
  if (!(largest > 0.0) || eig.eigenvalues().minCoeff() <= 1e-12 * largest) return std::nullopt;
  const Eigen::Quaterniond q(prev_rotation_xyzw[3], prev_rotation_xyzw[0], prev_rotation_xyzw[1],
                             prev_rotation_xyzw[2]);
  Matrix6 to_prev = Matrix6::Zero();  // world axes -> the previous keyframe's axes
  to_prev.topLeftCorner<3, 3>() = q.normalized().toRotationMatrix().transpose();
  to_prev.bottomRightCorner<3, 3>() = to_prev.topLeftCorner<3, 3>();
  const Matrix6 rotated = to_prev * growth * to_prev.transpose();
  const Matrix6 symmetric = 0.5 * (rotated + rotated.transpose());
  // One the graph can use (eigenvalues >= 1e-18, as LoopClosing checks): else the default model.
  if (CheckCovariance(symmetric)) return std::nullopt;
  std::array<double, 36> out;
  Eigen::Map<Matrix6>(out.data()) = symmetric;
  return out;
}

struct NodeCore::Impl {
  NodeParams params;
  NodeCallbacks callbacks;
  bool use_mapped_pixels = true;
  std::unique_ptr<LoopClosing> closing;

  // Inputs, guarded by mutex.
  mutable std::mutex mutex;
  std::condition_variable wake;
  std::optional<CameraIntrinsics> intrinsics;
  std::map<double, ImageData> images;
  std::map<double, PoseEntry> poses;
  std::optional<PoseEntry> last_keyframe_pose;  // of the last keyframe with a pose (worker only)
  std::map<double, std::vector<double>> points;
  double last_stamp = -std::numeric_limits<double>::infinity();  // of the last taken image
  bool finishing = false;
  NodeStats stats;
  double total_keyframe_ms = 0.0;

  // Keyframe stamps by id and the detected loops, guarded by records_mutex (read by the
  // optimiser's callback).
  mutable std::mutex records_mutex;
  std::vector<double> stamp_of_id;
  std::vector<LoopRecord> loops;

  std::thread worker;
  std::once_flag finish_once;
  std::string summary;

  void Warn(const std::string& text) {
    if (callbacks.on_warning) callbacks.on_warning(text);
  }

  // With the lock: whether the oldest image can go now.
  bool FrontReady() const {
    if (images.empty()) return false;
    if (finishing || static_cast<int>(images.size()) > params.image_queue) return true;
    if (!intrinsics) return false;
    const double stamp = images.begin()->first;
    const bool pose_done = !poses.empty() && poses.rbegin()->first >= stamp;
    const bool points_done =
        !params.wait_for_points || (!points.empty() && points.rbegin()->first >= stamp);
    return pose_done && points_done;
  }

  void Run() {
    std::unique_lock<std::mutex> lock(mutex);
    while (true) {
      wake.wait(lock, [&] { return FrontReady() || (finishing && images.empty()); });
      if (images.empty()) return;  // finishing
      auto node = images.extract(images.begin());
      const double stamp = node.key();
      last_stamp = stamp;
      stats.queued = static_cast<int64_t>(images.size());
      if (!intrinsics) {
        ++stats.dropped_no_camera_info;
        Warn(fmt::format("image {:.9f} dropped: no camera_info yet", stamp));
        continue;
      }
      std::optional<PoseEntry> pose = Nearest(poses, stamp, params.max_pose_dt);
      std::optional<std::vector<double>> xyz = Nearest(points, stamp, params.max_pose_dt);
      // Poses and points older than any image still to come are of no use.
      poses.erase(poses.begin(), poses.lower_bound(stamp - params.max_pose_dt));
      points.erase(points.begin(), points.lower_bound(stamp - params.max_pose_dt));
      const CameraIntrinsics k = *intrinsics;
      lock.unlock();
      Process(stamp, std::move(node.mapped()), k, pose, xyz);
      lock.lock();
    }
  }

  // The step covariance from the pose messages' covariances (StepCovarianceFromAbsolute), when
  // this keyframe and the previous one with a pose both carry one; counts the unusable ones.
  void SetStepCovariance(const PoseEntry& pose, KeyframeInput* input) {
    if (!last_keyframe_pose || AllZero(pose.covariance) ||
        AllZero(last_keyframe_pose->covariance)) {
      return;
    }
    const Eigen::Quaterniond q = last_keyframe_pose->pose.rotation;
    const auto step = StepCovarianceFromAbsolute({q.x(), q.y(), q.z(), q.w()},
                                                 last_keyframe_pose->covariance, pose.covariance);
    std::lock_guard<std::mutex> lock(mutex);
    if (!step) {
      if (stats.covariance_unusable++ == 0) {
        Warn(
            fmt::format("image {:.9f}: the pose covariance did not grow from the previous "
                        "keyframe's (not positive definite): the default odometry model is used "
                        "where that happens",
                        input->timestamp));
      }
      return;
    }
    input->odometry_covariance = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>(step->data());
    ++stats.keyframes_with_covariance;
  }

  void Process(double stamp, const ImageData& image, const CameraIntrinsics& k,
               const std::optional<PoseEntry>& pose,
               const std::optional<std::vector<double>>& xyz) {
    KeyframeInput input;
    try {
      input.image = bag_internal::DecodeGray(image);
    } catch (const MessageError& e) {
      Bad(fmt::format("image {:.9f} dropped: expected {}, got {}", stamp, e.expected, e.got));
      return;
    }
    if ((k.width > 0 && input.image.cols != k.width) ||
        (k.height > 0 && input.image.rows != k.height)) {
      Bad(fmt::format("image {:.9f} dropped: {}x{} pixels, camera_info says {}x{}", stamp,
                      input.image.cols, input.image.rows, k.width, k.height));
      return;
    }
    input.timestamp = stamp;
    input.intrinsics = k;
    if (pose) {
      input.world_from_cam = Sim3d(pose->pose);
      SetStepCovariance(*pose, &input);
    }
    if (xyz && use_mapped_pixels) {
      for (size_t i = 0; i + 2 < xyz->size(); i += 3) {
        const Eigen::Vector3d p((*xyz)[i], (*xyz)[i + 1], (*xyz)[i + 2]);
        if (!(p.z() > 0.0) || !p.allFinite()) continue;
        const Eigen::Vector2d uv = k.Project(p);
        if (uv.x() < 0 || uv.y() < 0 || uv.x() >= input.image.cols || uv.y() >= input.image.rows)
          continue;
        input.mapped_pixels.emplace_back(static_cast<float>(uv.x()), static_cast<float>(uv.y()));
        input.mapped_depths.push_back(static_cast<float>(p.z()));
      }
    }
    const auto start = std::chrono::steady_clock::now();
    LoopEvent event;
    {
      // Id and stamp are recorded before AddKeyframe so that a correction of this keyframe finds
      // its stamp (ids are 0, 1, ... : the index in stamp_of_id).
      std::lock_guard<std::mutex> lock(records_mutex);
      input.id = static_cast<int64_t>(stamp_of_id.size());
      stamp_of_id.push_back(stamp);
    }
    try {
      event = closing->AddKeyframe(input);
    } catch (const std::invalid_argument& e) {
      {
        std::lock_guard<std::mutex> lock(records_mutex);
        stamp_of_id.pop_back();
      }
      Bad(fmt::format("image {:.9f} dropped: {}", stamp, e.what()));
      return;
    }
    if (pose) last_keyframe_pose = pose;
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    {
      std::lock_guard<std::mutex> lock(mutex);
      ++stats.keyframes;
      stats.keyframes_without_pose += pose ? 0 : 1;
      stats.keyframes_with_points += input.mapped_pixels.empty() ? 0 : 1;
      stats.loops += event.result.detected() ? 1 : 0;
      total_keyframe_ms += ms;
    }
    if (!event.result.detected()) return;
    const LoopResult& r = event.result;
    LoopMessage m;
    {
      std::lock_guard<std::mutex> lock(records_mutex);
      m.query_stamp = stamp;
      m.match_stamp = stamp_of_id.at(static_cast<size_t>(r.match_id));
    }
    m.query_id = r.query_id;
    m.match_id = r.match_id;
    const Sim3d& s = r.match_from_query;
    m.translation = {s.translation.x(), s.translation.y(), s.translation.z()};
    m.rotation_xyzw = {s.rotation.x(), s.rotation.y(), s.rotation.z(), s.rotation.w()};
    m.scale = s.scale;
    m.inliers = r.inliers;
    m.score = r.score;
    m.pose_kind = ToString(r.pose_kind);
    m.in_graph = event.loop_in_graph;
    {
      std::lock_guard<std::mutex> lock(records_mutex);
      loops.push_back({m, event.loop_index});
    }
    if (callbacks.on_loop) callbacks.on_loop(m);
  }

  void Bad(const std::string& text) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      ++stats.dropped_bad;
    }
    Warn(text);
  }

  // The path of a solve: graph keyframes, their stamps, and the graph's loops PCM kept.
  PathMessage PathOf(uint64_t revision, const std::vector<int64_t>& ids,
                     const std::vector<Sim3d>& world_from_keyframe, size_t num_loops,
                     const std::vector<size_t>& rejected) const {
    PathMessage path;
    path.revision = revision;
    std::unordered_map<int64_t, size_t> row;
    std::lock_guard<std::mutex> lock(records_mutex);
    for (size_t i = 0; i < ids.size(); ++i) {
      const Sim3d& p = world_from_keyframe[i];
      row[ids[i]] = i;
      path.stamps.push_back(stamp_of_id.at(static_cast<size_t>(ids[i])));
      path.positions.push_back({p.translation.x(), p.translation.y(), p.translation.z()});
      path.rotations_xyzw.push_back(
          {p.rotation.x(), p.rotation.y(), p.rotation.z(), p.rotation.w()});
      path.scales.push_back(p.scale);
    }
    for (const LoopRecord& l : loops) {
      if (!Kept(l, num_loops, rejected)) continue;
      const auto q = row.find(l.message.query_id), m = row.find(l.message.match_id);
      if (q != row.end() && m != row.end()) path.loops.push_back({q->second, m->second});
    }
    return path;
  }

  void OnCorrection(const PoseCorrection& c) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      ++stats.solves;
    }
    if (callbacks.on_path) {
      callbacks.on_path(
          PathOf(c.revision, c.ids, c.world_from_keyframe, c.num_loops, c.summary.rejected_loops));
    }
  }

  std::string DoFinish() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      finishing = true;
    }
    wake.notify_all();
    if (worker.joinable()) worker.join();
    closing->Finish();
    nlohmann::json out;
    PathMessage path;
    std::vector<size_t> rejected;
    if (closing->options().optimize) {
      const CorrectedKeyframes c = closing->Corrections();
      const auto latest = closing->LatestSolve();
      if (latest) rejected = latest->summary.rejected_loops;
      path = PathOf(c.revision, c.ids, c.world_from_keyframe, closing->num_loops(), rejected);
      if (callbacks.on_path) callbacks.on_path(path);
    }
    std::vector<LoopRecord> records;
    {
      std::lock_guard<std::mutex> lock(records_mutex);
      records = loops;
    }
    const auto accepted = [&](const LoopRecord& l) {
      return closing->options().optimize && Kept(l, closing->num_loops(), rejected);
    };
    if (!params.trajectory_file.empty()) {
      Trajectory traj;
      traj.has_rotation = true;
      traj.has_timestamps = true;
      for (size_t i = 0; i < path.stamps.size(); ++i) {
        const auto& t = path.positions[i];
        const auto& q = path.rotations_xyzw[i];
        traj.poses.push_back(StampedPose{path.stamps[i], static_cast<int64_t>(i),
                                         Rigid3d(Eigen::Quaterniond(q[3], q[0], q[1], q[2]),
                                                 Eigen::Vector3d(t[0], t[1], t[2]))});
      }
      WriteTrajectory(params.trajectory_file, traj, TrajectoryFormat::kTum);
    }
    nlohmann::json loop_rows = nlohmann::json::array();
    std::string csv =
        "query_stamp,match_stamp,query,match,inliers,score,pose_kind,in_graph,accepted\n";
    for (const LoopRecord& l : records) {
      const LoopMessage& m = l.message;
      const bool ok = accepted(l);
      csv += fmt::format("{:.9f},{:.9f},{},{},{},{:.6f},{},{},{}\n", m.query_stamp, m.match_stamp,
                         m.query_id, m.match_id, m.inliers, m.score, m.pose_kind, int{m.in_graph},
                         int{ok});
      loop_rows.push_back({{"query_stamp", m.query_stamp},
                           {"match_stamp", m.match_stamp},
                           {"query", m.query_id},
                           {"match", m.match_id},
                           {"inliers", m.inliers},
                           {"score", m.score},
                           {"pose_kind", m.pose_kind},
                           {"in_graph", m.in_graph},
                           {"accepted", ok}});
    }
    if (!params.loops_file.empty()) {
      WriteFileAtomically(params.loops_file, [&](std::ostream& os) { os << csv; });
    }
    for (const auto& [name, value] : Snapshot().Fields()) out[name] = value;
    out["path_keyframes"] = path.stamps.size();
    out["loops"] = loop_rows;
    return out.dump();
  }

  NodeStats Snapshot() const {
    std::lock_guard<std::mutex> lock(mutex);
    NodeStats s = stats;
    s.queued = static_cast<int64_t>(images.size());
    s.mean_keyframe_ms = s.keyframes > 0 ? total_keyframe_ms / s.keyframes : 0.0;
    return s;
  }
};

NodeCore::NodeCore(const NodeParams& params, NodeCallbacks callbacks)
    : impl_(std::make_unique<Impl>()) {
  params.Check();
  Impl& s = *impl_;
  s.params = params;
  s.callbacks = std::move(callbacks);
  const PipelineOptions p = PipelineOptionsFrom(params);
  s.use_mapped_pixels = p.use_mapped_pixels;
  s.closing =
      std::make_unique<LoopClosing>(LoopClosingOptionsFor(p, params.solve_while_running),
                                    [this](const PoseCorrection& c) { impl_->OnCorrection(c); });
  s.worker = std::thread([this] { impl_->Run(); });
}

NodeCore::~NodeCore() {
  try {
    Finish();
  } catch (const std::exception& e) {
    impl_->Warn(fmt::format("finishing: {}", e.what()));
  }
}

void NodeCore::AddCameraInfo(const bag_internal::CameraInfoMessage& info) {
  Impl& s = *impl_;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    if (s.intrinsics) return;  // the first one holds (a vSLAM's camera does not change)
  }
  CameraIntrinsics k;
  try {
    k = bag_internal::IntrinsicsFromCameraInfo(info);
  } catch (const MessageError& e) {
    s.Bad(fmt::format("camera_info ignored: expected {}, got {}", e.expected, e.got));
    return;
  }
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    s.intrinsics = k;
  }
  s.wake.notify_all();
}

void NodeCore::AddImage(ImageData image) {
  Impl& s = *impl_;
  const double stamp = image.header.stamp;
  std::string warning;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    ++s.stats.images;
    if (s.finishing) return;
    if (!(stamp > s.last_stamp) || s.images.count(stamp)) {
      ++s.stats.dropped_out_of_order;
      warning =
          fmt::format("image {:.9f} dropped: stamped at or before an image already taken", stamp);
    } else {
      s.images.emplace(stamp, std::move(image));
    }
  }
  if (!warning.empty()) s.Warn(warning);
  s.wake.notify_all();
}

void NodeCore::AddPose(const bag_internal::PoseMessage& pose) {
  Impl& s = *impl_;
  Rigid3d p;
  try {
    p = bag_internal::PoseOf(pose);
  } catch (const MessageError& e) {
    s.Bad(fmt::format("pose {:.9f} ignored: expected {}, got {}", pose.stamp, e.expected, e.got));
    return;
  }
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    ++s.stats.poses;
    PoseEntry& entry = s.poses[pose.stamp];
    entry.pose = p;
    std::copy(std::begin(pose.covariance), std::end(pose.covariance), entry.covariance.begin());
    while (static_cast<int>(s.poses.size()) > s.params.pose_buffer) s.poses.erase(s.poses.begin());
  }
  s.wake.notify_all();
}

void NodeCore::AddMappedPoints(double stamp, std::vector<double> xyz) {
  Impl& s = *impl_;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    s.points[stamp] = std::move(xyz);
    while (static_cast<int>(s.points.size()) > s.params.image_queue + 1)
      s.points.erase(s.points.begin());
  }
  s.wake.notify_all();
}

std::string NodeCore::Finish() {
  std::call_once(impl_->finish_once, [this] { impl_->summary = impl_->DoFinish(); });
  return impl_->summary;
}

NodeStats NodeCore::Stats() const { return impl_->Snapshot(); }

}  // namespace sparseloop::ros_node
