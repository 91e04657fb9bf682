// sparseloop_node: the ROS 1 node (docs/ROS.md). Only the ROS side lives here (C++17: ROS 1 headers
// do not compile as C++20); the logic is NodeCore (node_core.h), which sees plain structs.
//
// Subscribes:  image (sensor_msgs/Image) or <image>/compressed (~image_transport: compressed),
//              camera_info (sensor_msgs/CameraInfo), the raw vSLAM pose (~pose_type: pose =
//              geometry_msgs/PoseStamped, pose_cov = PoseWithCovarianceStamped, odometry =
//              nav_msgs/Odometry, tf = the TF transform ~world_frame <- ~camera_frame at the image
//              stamp), mapped_points (sensor_msgs/PointCloud2, x y z float32 or float64, camera
//              frame).
// Publishes:   ~loops (std_msgs/Float64MultiArray, one per detected loop, layout below),
//              ~path (nav_msgs/Path, latched: the corrected keyframe trajectory after each solve),
//              ~markers (visualization_msgs/MarkerArray, latched: keyframes and kept loops).
//              /diagnostics (diagnostic_msgs/DiagnosticArray, every ~diagnostics_period s: the
//              counters of NodeStats as key-values; also one log line).
// Service:     ~finish (std_srvs/Trigger): process what is queued, final solve, publish, write the
//              files; the response's message is the JSON summary. Shutdown does the same.
#include <ros/ros.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <iomanip>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_msgs/Header.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>
#include <nlohmann/json.hpp>

#include "bag/ros_convert.h"
#include "ros/node_core.h"

namespace sparseloop::ros_node {
namespace {

// ~loops: one row of kLoopFields values per message (layout.dim[0] "loop" size 1, dim[1] "field").
constexpr const char* kLoopFields[] = {"query_stamp", "match_stamp", "query_id",  "match_id",
                                       "tx",          "ty",          "tz",        "qx",
                                       "qy",          "qz",          "qw",        "scale",
                                       "inliers",     "score",       "pose_kind", "in_graph"};
constexpr size_t kNumLoopFields = sizeof(kLoopFields) / sizeof(kLoopFields[0]);

double PoseKindCode(const std::string& kind) {
  return kind == "se3_unit_translation" ? 1 : kind == "se3_metric" ? 2 : kind == "sim3" ? 3 : 0;
}

// The node's own private parameters; any other private name except config is an error.
const std::set<std::string> kNodeParams = {
    "preset",      "config",      "config_file",     "solve_while_running", "max_pose_dt",
    "image_queue", "pose_buffer", "wait_for_points", "trajectory_file",     "loops_file",
    "pose_type",   "world_frame", "camera_frame",    "image_transport",     "diagnostics_period"};

// An integer parameter in [lo, hi], `fallback` when unset. The value is read as given: roscpp
// stores `_image_queue:=3000000000` as a double, which an int parameter turned into -2147483648.
int IntParam(ros::NodeHandle& pnh, const std::string& name, int fallback, int lo, int hi) {
  XmlRpc::XmlRpcValue v;
  if (!pnh.getParam(name, v)) return fallback;
  const bool is_int = v.getType() == XmlRpc::XmlRpcValue::TypeInt;
  const bool is_double = v.getType() == XmlRpc::XmlRpcValue::TypeDouble;
  const double d = is_int      ? static_cast<double>(static_cast<int>(v))
                   : is_double ? static_cast<double>(v)
                               : 0.0;
  if (!(is_int || is_double) || d != std::floor(d) || d < lo || d > hi) {
    std::ostringstream message;
    message << pnh.resolveName(name) << " must be an integer in [" << lo << ", " << hi << "], got ";
    if (is_int || is_double) {
      message << std::fixed << std::setprecision(std::floor(d) == d ? 0 : 6) << d;
    } else {
      message << "a value of another type";
    }
    throw std::invalid_argument(message.str());
  }
  return static_cast<int>(d);
}

// A string parameter, `fallback` when unset. Another type is an error naming the parameter:
// roscpp's param<std::string> took the fallback silently, so `_preset:=1` or
// `_trajectory_file:=123` (read as numbers) ran with the defaults and no trajectory file.
std::string StringParam(ros::NodeHandle& pnh, const std::string& name,
                        const std::string& fallback) {
  XmlRpc::XmlRpcValue v;
  if (!pnh.getParam(name, v)) return fallback;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeString) {
    std::ostringstream got;
    got << v;
    throw std::invalid_argument(pnh.resolveName(name) + " must be a string, got " + got.str() +
                                " (a value that reads as a number or boolean needs quotes: _" +
                                name + ":=\"'...'\")");
  }
  return static_cast<std::string>(v);
}

nlohmann::json ToJson(XmlRpc::XmlRpcValue& v, const std::string& name) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return static_cast<bool>(v);
    case XmlRpc::XmlRpcValue::TypeInt:
      return static_cast<int>(v);
    case XmlRpc::XmlRpcValue::TypeDouble:
      return static_cast<double>(v);
    case XmlRpc::XmlRpcValue::TypeString:
      return static_cast<std::string>(v);
    case XmlRpc::XmlRpcValue::TypeArray: {
      nlohmann::json a = nlohmann::json::array();
      for (int i = 0; i < v.size(); ++i) a.push_back(ToJson(v[i], name));
      return a;
    }
    case XmlRpc::XmlRpcValue::TypeStruct: {
      nlohmann::json o = nlohmann::json::object();
      for (auto& kv : v) o[kv.first] = ToJson(kv.second, name + "/" + kv.first);
      return o;
    }
    default:
      throw std::invalid_argument(name + ": a boolean, number, string, list or dictionary");
  }
}

class Node {
 public:
  Node(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh), pnh_(pnh) {
    CheckParamNames();
    NodeParams p;
    XmlRpc::XmlRpcValue config;
    if (pnh.getParam("config", config)) {
      if (config.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
        throw std::invalid_argument(pnh.resolveName("config") +
                                    " must be a dictionary of config keys");
      }
      p.config_json = ToJson(config, pnh.resolveName("config")).dump();
    }
    p.preset = StringParam(pnh, "preset", "");
    p.config_file = StringParam(pnh, "config_file", "");
    pnh.param("solve_while_running", p.solve_while_running, p.solve_while_running);
    pnh.param("max_pose_dt", p.max_pose_dt, p.max_pose_dt);
    p.image_queue = IntParam(pnh, "image_queue", p.image_queue, 1, 100000);
    p.pose_buffer = IntParam(pnh, "pose_buffer", p.pose_buffer, 1, 100000000);
    pnh.param("wait_for_points", p.wait_for_points, p.wait_for_points);
    p.trajectory_file = StringParam(pnh, "trajectory_file", "");
    p.loops_file = StringParam(pnh, "loops_file", "");
    pose_type_ = StringParam(pnh, "pose_type", "pose");
    world_frame_ = StringParam(pnh, "world_frame", "world");
    camera_frame_ = StringParam(pnh, "camera_frame", "camera");
    transport_ = StringParam(pnh, "image_transport", "raw");
    pnh.param("diagnostics_period", diagnostics_period_, 1.0);
    if (!(diagnostics_period_ >= 0.0 && diagnostics_period_ <= 3600.0)) {
      std::ostringstream message;
      message << pnh.resolveName("diagnostics_period")
              << " must be in [0, 3600] s (0: no diagnostics), got " << diagnostics_period_;
      throw std::invalid_argument(message.str());
    }
    if (pose_type_ != "pose" && pose_type_ != "pose_cov" && pose_type_ != "odometry" &&
        pose_type_ != "tf") {
      throw std::invalid_argument(pnh.resolveName("pose_type") +
                                  " must be pose, pose_cov, odometry or tf, got '" + pose_type_ +
                                  "'");
    }
    if (transport_ != "raw" && transport_ != "compressed") {
      throw std::invalid_argument(pnh.resolveName("image_transport") +
                                  " must be raw or compressed, got '" + transport_ + "'");
    }

    loops_pub_ = pnh.advertise<std_msgs::Float64MultiArray>("loops", 100);
    path_pub_ = pnh.advertise<nav_msgs::Path>("path", 1, /*latch=*/true);
    markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 1, /*latch=*/true);
    diag_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    NodeCallbacks callbacks;
    callbacks.on_loop = [this](const LoopMessage& m) { PublishLoop(m); };
    callbacks.on_path = [this](const PathMessage& m) { PublishPath(m); };
    callbacks.on_warning = [](const std::string& text) { ROS_WARN("%s", text.c_str()); };
    core_ = std::make_unique<NodeCore>(p, std::move(callbacks));

    // Subscriber queues are generous: NodeCore's own queue is the bounded one that decides.
    if (transport_ == "raw") {
      image_sub_ = nh.subscribe("image", 100, &Node::OnImage, this);
    } else {
      // As image_transport does: the base topic (remapped as `image`) + "/compressed".
      image_sub_ = nh.subscribe(nh.resolveName("image") + "/compressed", 100,
                                &Node::OnCompressedImage, this);
    }
    info_sub_ = nh.subscribe("camera_info", 10, &Node::OnCameraInfo, this);
    points_sub_ = nh.subscribe("mapped_points", 100, &Node::OnPoints, this);
    if (pose_type_ == "pose") {
      pose_sub_ = nh.subscribe("pose", 1000, &Node::OnPoseStamped, this);
    } else if (pose_type_ == "pose_cov") {
      pose_sub_ = nh.subscribe("pose", 1000, &Node::OnPoseCov, this);
    } else if (pose_type_ == "odometry") {
      pose_sub_ = nh.subscribe("pose", 1000, &Node::OnOdometry, this);
    } else {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>(ros::Duration(60.0));
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
      tf_timer_ = nh.createTimer(ros::Duration(0.05), &Node::LookupPending, this);
    }
    finish_srv_ = pnh.advertiseService("finish", &Node::OnFinish, this);
    if (diagnostics_period_ > 0) {
      diag_timer_ =
          nh.createWallTimer(ros::WallDuration(diagnostics_period_), &Node::Diagnostics, this);
    }
    ROS_INFO("sparseloop_node: images on %s (%s), poses from %s (%s), loops on %s",
             image_sub_.getTopic().c_str(), transport_.c_str(),
             pose_type_ == "tf" ? (world_frame_ + " <- " + camera_frame_).c_str()
                                : pose_sub_.getTopic().c_str(),
             pose_type_.c_str(), loops_pub_.getTopic().c_str());
  }

  std::string Finish() { return core_->Finish(); }

 private:
  void CheckParamNames() {
    std::vector<std::string> names;
    ros::param::getParamNames(names);
    const std::string ns = pnh_.getNamespace() + "/";
    for (const std::string& n : names) {
      if (n.rfind(ns, 0) != 0) continue;
      const std::string rest = n.substr(ns.size());
      const std::string first = rest.substr(0, rest.find('/'));
      if (!kNodeParams.count(first)) {
        std::string valid;
        for (const auto& k : kNodeParams) valid += (valid.empty() ? "" : ", ") + k;
        throw std::invalid_argument("unknown parameter " + n + " (valid: " + valid +
                                    "; config keys go under " + ns + "config/)");
      }
    }
  }

  void SetFrame(const std::string& frame_id) {
    std::lock_guard<std::mutex> lock(frame_mutex_);
    if (!frame_id.empty()) frame_id_ = frame_id;
  }
  std::string Frame() {
    std::lock_guard<std::mutex> lock(frame_mutex_);
    return frame_id_.empty() ? world_frame_ : frame_id_;
  }

  void OnImage(const sensor_msgs::Image::ConstPtr& msg) {
    TrackForTf(msg->header.stamp);
    core_->AddImage(bag_internal::ToImageData(*msg, image_index_++));
  }
  void OnCompressedImage(const sensor_msgs::CompressedImage::ConstPtr& msg) {
    TrackForTf(msg->header.stamp);
    core_->AddImage(bag_internal::ToImageData(*msg, image_index_++));
  }
  void OnCameraInfo(const sensor_msgs::CameraInfo::ConstPtr& msg) {
    core_->AddCameraInfo(bag_internal::ToCameraInfo(*msg));
  }
  void OnPoseStamped(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    SetFrame(msg->header.frame_id);
    core_->AddPose(bag_internal::ToPoseMessage(pose_index_++, msg->header.stamp, msg->pose.position,
                                               msg->pose.orientation));
  }
  // The pose's covariance goes along: consecutive keyframes' covariances give the odometry
  // edge's (NodeCore, StepCovarianceFromAbsolute).
  template <typename PoseWithCovariance>
  void AddPoseWithCovariance(const std_msgs::Header& header, const PoseWithCovariance& pose) {
    SetFrame(header.frame_id);
    bag_internal::PoseMessage m = bag_internal::ToPoseMessage(
        pose_index_++, header.stamp, pose.pose.position, pose.pose.orientation);
    std::copy(pose.covariance.begin(), pose.covariance.end(), m.covariance);
    core_->AddPose(m);
  }
  void OnPoseCov(const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& msg) {
    AddPoseWithCovariance(msg->header, msg->pose);
  }
  void OnOdometry(const nav_msgs::Odometry::ConstPtr& msg) {
    AddPoseWithCovariance(msg->header, msg->pose);
  }
  void OnPoints(const sensor_msgs::PointCloud2::ConstPtr& msg) {
    std::vector<double> xyz;
    try {
      uint8_t type = 0;
      int found = 0;
      for (const auto& f : msg->fields) {
        if (f.name == "x" || f.name == "y" || f.name == "z") {
          if (found > 0 && f.datatype != type) throw std::runtime_error("x, y, z of mixed types");
          type = f.datatype;
          ++found;
        }
      }
      if (found != 3) throw std::runtime_error("no x, y, z fields");
      if (msg->is_bigendian) throw std::runtime_error("big-endian data");
      xyz.reserve(size_t{msg->width} * msg->height * 3);
      if (type == sensor_msgs::PointField::FLOAT32) {
        ReadXyz<float>(*msg, &xyz);
      } else if (type == sensor_msgs::PointField::FLOAT64) {
        ReadXyz<double>(*msg, &xyz);
      } else {
        throw std::runtime_error("x, y, z of datatype " + std::to_string(type));
      }
    } catch (const std::exception& e) {
      ROS_WARN("mapped_points %.9f ignored: %s (float32 or float64 x y z expected)",
               msg->header.stamp.toSec(), e.what());
      return;
    }
    core_->AddMappedPoints(msg->header.stamp.toSec(), std::move(xyz));
  }
  template <typename T>
  static void ReadXyz(const sensor_msgs::PointCloud2& msg, std::vector<double>* xyz) {
    for (sensor_msgs::PointCloud2ConstIterator<T> x(msg, "x"), y(msg, "y"), z(msg, "z");
         x != x.end(); ++x, ++y, ++z) {
      xyz->insert(xyz->end(),
                  {static_cast<double>(*x), static_cast<double>(*y), static_cast<double>(*z)});
    }
  }

  // TF poses: each image stamp is looked up until the transform is there (or 10 s passed).
  void TrackForTf(const ros::Time& stamp) {
    if (pose_type_ != "tf") return;
    if (stamp.isZero()) {  // a TF lookup at time 0 means "the latest": no pose for this image
      ROS_WARN_THROTTLE(5.0, "image stamped 0: no TF lookup (time 0 means the latest transform)");
      return;
    }
    std::lock_guard<std::mutex> lock(tf_mutex_);
    pending_.push_back(stamp);
  }
  void LookupPending(const ros::TimerEvent&) {
    std::vector<ros::Time> pending;
    {
      std::lock_guard<std::mutex> lock(tf_mutex_);
      pending.swap(pending_);
    }
    std::vector<ros::Time> keep;
    for (const ros::Time& stamp : pending) {
      try {
        const geometry_msgs::TransformStamped t =
            tf_buffer_->lookupTransform(world_frame_, camera_frame_, stamp);
        core_->AddPose(bag_internal::ToPoseMessage(pose_index_++, stamp, t.transform.translation,
                                                   t.transform.rotation));
      } catch (const tf2::TransformException& e) {
        if ((ros::Time::now() - stamp).toSec() < 10.0) {
          keep.push_back(stamp);
        } else {
          ROS_WARN_THROTTLE(5.0, "no TF %s <- %s at %.9f: %s", world_frame_.c_str(),
                            camera_frame_.c_str(), stamp.toSec(), e.what());
        }
      }
    }
    std::lock_guard<std::mutex> lock(tf_mutex_);
    pending_.insert(pending_.begin(), keep.begin(), keep.end());
  }

  void PublishLoop(const LoopMessage& m) {
    std_msgs::Float64MultiArray a;
    a.layout.dim.resize(2);
    a.layout.dim[0].label = "loop";
    a.layout.dim[0].size = 1;
    a.layout.dim[0].stride = kNumLoopFields;
    a.layout.dim[1].label =
        "query_stamp,match_stamp,query_id,match_id,tx,ty,tz,qx,qy,qz,qw,"
        "scale,inliers,score,pose_kind,in_graph";
    a.layout.dim[1].size = kNumLoopFields;
    a.layout.dim[1].stride = kNumLoopFields;
    a.data = {m.query_stamp,
              m.match_stamp,
              static_cast<double>(m.query_id),
              static_cast<double>(m.match_id),
              m.translation[0],
              m.translation[1],
              m.translation[2],
              m.rotation_xyzw[0],
              m.rotation_xyzw[1],
              m.rotation_xyzw[2],
              m.rotation_xyzw[3],
              m.scale,
              static_cast<double>(m.inliers),
              m.score,
              PoseKindCode(m.pose_kind),
              m.in_graph ? 1.0 : 0.0};
    loops_pub_.publish(a);
  }

  void PublishPath(const PathMessage& m) {
    const std::string frame = Frame();
    nav_msgs::Path path;
    path.header.stamp = m.stamps.empty() ? ros::Time(0) : ros::Time(m.stamps.back());
    path.header.frame_id = frame;
    path.header.seq = static_cast<uint32_t>(m.revision);
    visualization_msgs::MarkerArray markers;
    visualization_msgs::Marker kf, loops;
    kf.header = path.header;
    kf.ns = "keyframes";
    kf.type = visualization_msgs::Marker::LINE_STRIP;
    kf.scale.x = 0.05;
    kf.color.g = 0.8f, kf.color.b = 1.0f, kf.color.a = 1.0f;
    kf.pose.orientation.w = 1.0;
    loops = kf;
    loops.ns = "loops";
    loops.type = visualization_msgs::Marker::LINE_LIST;
    loops.color.r = 1.0f, loops.color.g = 0.2f, loops.color.b = 0.2f;
    for (size_t i = 0; i < m.stamps.size(); ++i) {
      geometry_msgs::PoseStamped p;
      p.header.frame_id = frame;
      p.header.stamp = ros::Time(m.stamps[i]);
      p.pose.position.x = m.positions[i][0];
      p.pose.position.y = m.positions[i][1];
      p.pose.position.z = m.positions[i][2];
      p.pose.orientation.x = m.rotations_xyzw[i][0];
      p.pose.orientation.y = m.rotations_xyzw[i][1];
      p.pose.orientation.z = m.rotations_xyzw[i][2];
      p.pose.orientation.w = m.rotations_xyzw[i][3];
      path.poses.push_back(p);
      kf.points.push_back(p.pose.position);
    }
    for (const auto& l : m.loops) {
      loops.points.push_back(path.poses[l[0]].pose.position);
      loops.points.push_back(path.poses[l[1]].pose.position);
    }
    markers.markers = {kf, loops};
    path_pub_.publish(path);
    markers_pub_.publish(markers);
  }

  bool OnFinish(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    try {
      res.message = core_->Finish();
      res.success = true;
    } catch (const std::exception& e) {
      res.message = e.what();
      res.success = false;
    }
    return true;
  }

  void Diagnostics(const ros::WallTimerEvent&) {
    const NodeStats s = core_->Stats();
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.name = ros::this_node::getName();
    status.hardware_id = "sparseloop";
    status.level = s.dropped_bad + s.dropped_out_of_order + s.dropped_no_camera_info > 0
                       ? diagnostic_msgs::DiagnosticStatus::WARN
                       : diagnostic_msgs::DiagnosticStatus::OK;
    status.message = s.keyframes > 0 ? "running" : "waiting for images";
    for (const auto& [key, value] : s.Fields()) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = std::to_string(value);
      status.values.push_back(kv);
    }
    array.status.push_back(status);
    diag_pub_.publish(array);
    ROS_INFO(
        "sparseloop: %lld images, %lld keyframes (%lld without pose), %lld queued, %lld loops, "
        "%lld solves, %.1f ms/keyframe, dropped %lld out of order / %lld before camera_info "
        "/ %lld bad",
        static_cast<long long>(s.images), static_cast<long long>(s.keyframes),
        static_cast<long long>(s.keyframes_without_pose), static_cast<long long>(s.queued),
        static_cast<long long>(s.loops), static_cast<long long>(s.solves), s.mean_keyframe_ms,
        static_cast<long long>(s.dropped_out_of_order),
        static_cast<long long>(s.dropped_no_camera_info), static_cast<long long>(s.dropped_bad));
  }

  ros::NodeHandle& nh_;
  ros::NodeHandle& pnh_;
  std::string pose_type_, world_frame_, camera_frame_, transport_;
  double diagnostics_period_ = 1.0;
  std::mutex frame_mutex_;
  std::string frame_id_;
  int64_t image_index_ = 0;
  int64_t pose_index_ = 0;
  std::unique_ptr<NodeCore> core_;
  ros::Publisher loops_pub_, path_pub_, markers_pub_, diag_pub_;
  ros::Subscriber image_sub_, info_sub_, pose_sub_, points_sub_;
  ros::ServiceServer finish_srv_;
  ros::WallTimer diag_timer_;
  ros::Timer tf_timer_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::mutex tf_mutex_;
  std::vector<ros::Time> pending_;
};

}  // namespace
}  // namespace sparseloop::ros_node

namespace {

// `sparseloop_node --help`: what it subscribes and publishes, without a ROS master.
bool AskedForHelp(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") return true;
  }
  return false;
}

constexpr const char* kUsage =
    "Usage: sparseloop_node [__name:=NAME] [image:=TOPIC] [camera_info:=TOPIC] [pose:=TOPIC]\n"
    "                       [mapped_points:=TOPIC] [_PARAM:=VALUE ...]\n"
    "The sparseloop loop closer as a ROS 1 node (docs/ROS.md); needs a ROS master.\n"
    "Subscribes image, camera_info, pose (~pose_type) and mapped_points; publishes ~loops, ~path,\n"
    "~markers and /diagnostics; service ~finish. Private parameters: preset (sparse|dense),\n"
    "config (a dictionary of `sparseloop config --dump` keys), config_file,\n"
    "solve_while_running, max_pose_dt,\n"
    "image_queue, pose_buffer, wait_for_points, trajectory_file, loops_file, pose_type\n"
    "(pose|pose_cov|odometry|tf), world_frame, camera_frame, image_transport (raw|compressed),\n"
    "diagnostics_period.\n";

}  // namespace

int main(int argc, char** argv) {
  if (AskedForHelp(argc, argv)) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  ros::init(argc, argv, "sparseloop");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  std::unique_ptr<sparseloop::ros_node::Node> node;
  try {
    node = std::make_unique<sparseloop::ros_node::Node>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_FATAL("sparseloop_node: %s", e.what());
    return 2;
  }
  ros::AsyncSpinner spinner(2);  // the finish service may wait while topics keep coming
  spinner.start();
  ros::waitForShutdown();
  try {
    const std::string summary = node->Finish();
    std::fprintf(stderr, "sparseloop_node: finished: %s\n", summary.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sparseloop_node: finishing failed: %s\n", e.what());
    return 1;
  }
  return 0;
}
