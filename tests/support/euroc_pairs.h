#pragma once
// euroc_loop_pairs (Kimera-VIO's loop-closure test data): GT camera poses, stereo calibration,
// images, the stereo-mapped pixels + depths a stereo vSLAM would hand over, and one detector run
// per pair. No test framework: shared by tests/loop and bench/detector_accuracy.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/loop/loop_detector.h"

namespace sparseloop::test {

// EuRoC: body poses + T_BS extrinsic, radtan lens.
inline Eigen::Matrix4d EurocBodyFromCam(int cam) {
  Eigen::Matrix4d t_bs;
  if (cam == 0) {  // sensorLeft.yaml T_BS
    t_bs << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008,
        0.0149672133247, 0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797,
        0.999660727178, 0.00981073058949, 0, 0, 0, 1;
  } else {  // sensorRight.yaml T_BS
    t_bs << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556, 0.999598781151,
        0.0130119051815, 0.0251588363115, 0.0453689425024, -0.0253898008918, 0.0179005838253,
        0.999517347078, 0.00786212447038, 0, 0, 0, 1;
  }
  return t_bs;
}

inline Rigid3d EurocCam(double qw, double qx, double qy, double qz, double tx, double ty,
                        double tz) {
  const Rigid3d body_from_cam = Rigid3d::FromMatrix3x4(EurocBodyFromCam(0).topRows<3>(), 1e-4);
  const Rigid3d world_from_body(Eigen::Quaterniond(qw, qx, qy, qz), Eigen::Vector3d(tx, ty, tz));
  return world_from_body * body_from_cam;
}

inline CameraIntrinsics EurocIntrinsics(int cam) {
  CameraIntrinsics k;
  k.width = 752;
  k.height = 480;
  k.distortion_model = DistortionModel::kRadialTangential;
  if (cam == 0) {  // sensorLeft.yaml
    k.fx = 458.654;
    k.fy = 457.296;
    k.cx = 367.215;
    k.cy = 248.375;
    k.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  } else {  // sensorRight.yaml
    k.fx = 457.587;
    k.fy = 456.134;
    k.cx = 379.999;
    k.cy = 255.238;
    k.distortion = {-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05};
  }
  return k;
}

// `root` is the euroc_loop_pairs folder; throws std::runtime_error when the image is missing.
inline cv::Mat EurocImage(const std::filesystem::path& root, const std::string& side, int i) {
  const std::filesystem::path path = root / (side + "_img_" + std::to_string(i) + ".png");
  cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) throw std::runtime_error("cannot read EuRoC image " + path.string());
  return image;
}

// What a stereo vSLAM (Kimera-VIO, where these pairs come from) hands over: the left-image
// pixels it mapped and their depth. Here: the left image's 2000 ORB corners, with the depth of
// a semi-global stereo match (OpenCV StereoSGBM on the rectified pair, 1/16 px disparities) at
// each; depth = z in the (unrectified) left camera, metres. A sparse ORB left/right match with
// linear triangulation was tried first: its ~1 px disparity noise (~10 % depth at 4 m) left
// pair (2,3) 5.1 deg off (docs/DETECTOR.md).
struct StereoPoints {
  std::vector<cv::Point2f> pixels;
  std::vector<float> depths;
};

inline StereoPoints EurocStereoPoints(const std::filesystem::path& root, int i) {
  const cv::Mat left = EurocImage(root, "left", i), right = EurocImage(root, "right", i);
  const CameraIntrinsics kl = EurocIntrinsics(0), kr = EurocIntrinsics(1);
  const cv::Matx33d ml(kl.fx, 0, kl.cx, 0, kl.fy, kl.cy, 0, 0, 1);
  const cv::Matx33d mr(kr.fx, 0, kr.cx, 0, kr.fy, kr.cy, 0, 0, 1);
  const Eigen::Matrix4d right_from_left = EurocBodyFromCam(1).inverse() * EurocBodyFromCam(0);
  cv::Matx33d r;
  cv::Vec3d t;
  for (int a = 0; a < 3; ++a) {
    t[a] = right_from_left(a, 3);
    for (int b = 0; b < 3; ++b) r(a, b) = right_from_left(a, b);
  }
  const cv::Size size(left.cols, left.rows);
  cv::Mat r1, r2, p1, p2, q;
  cv::stereoRectify(ml, kl.distortion, mr, kr.distortion, size, r, t, r1, r2, p1, p2, q,
                    cv::CALIB_ZERO_DISPARITY, 0.0);
  cv::Mat lx, ly, rx, ry, left_rect, right_rect;
  cv::initUndistortRectifyMap(ml, kl.distortion, r1, p1, size, CV_32FC1, lx, ly);
  cv::initUndistortRectifyMap(mr, kr.distortion, r2, p2, size, CV_32FC1, rx, ry);
  cv::remap(left, left_rect, lx, ly, cv::INTER_LINEAR);
  cv::remap(right, right_rect, rx, ry, cv::INTER_LINEAR);
  cv::Ptr<cv::StereoSGBM> sgbm =
      cv::StereoSGBM::create(0, 64, 5, 8 * 25, 32 * 25, 0, 0, 10, 100, 2, cv::StereoSGBM::MODE_HH);
  cv::Mat disparity16;
  sgbm->compute(left_rect, right_rect, disparity16);
  const double f = p1.at<double>(0, 0), cx = p1.at<double>(0, 2), cy = p1.at<double>(1, 2);
  const double baseline = -p2.at<double>(0, 3) / p2.at<double>(0, 0);
  std::vector<cv::KeyPoint> corners;
  cv::ORB::create(2000)->detect(left, corners);
  std::vector<cv::Point2f> pixels, rectified;
  for (const cv::KeyPoint& k : corners) pixels.push_back(k.pt);
  cv::undistortPoints(pixels, rectified, ml, kl.distortion, r1, p1);
  Eigen::Matrix3d rect_from_left;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) rect_from_left(a, b) = r1.at<double>(a, b);
  StereoPoints out;
  for (size_t k = 0; k < pixels.size(); ++k) {
    const int u = static_cast<int>(std::lround(rectified[k].x));
    const int v = static_cast<int>(std::lround(rectified[k].y));
    if (u < 0 || v < 0 || u >= disparity16.cols || v >= disparity16.rows) continue;
    const double d = disparity16.at<int16_t>(v, u) / 16.0;
    if (d < 0.5) continue;  // invalid (negative) or beyond ~90 m
    const double z = f * baseline / d;
    const Eigen::Vector3d in_rect((rectified[k].x - cx) * z / f, (rectified[k].y - cy) * z / f, z);
    const Eigen::Vector3d in_left = rect_from_left.transpose() * in_rect;
    if (in_left.z() < 0.2 || in_left.z() > 30.0) continue;
    out.pixels.push_back(pixels[k]);
    out.depths.push_back(static_cast<float>(in_left.z()));
  }
  return out;
}

struct EurocPairResult {
  LoopResult result;
  double rotation_error_deg = 0;
  double translation_error_m = -1;  // with depths (metric PnP / Sim(3)); -1 otherwise
  double translation_direction_error_deg = 0;
  double baseline_m = 0;  // GT distance between the two cameras
};

// Pair 0 = images (0, 1), pair 1 = images (2, 3); match first, then the query. `stereo`: the
// keyframes carry the stereo-mapped pixels and depths (a stereo / RGB-D vSLAM's input).
inline EurocPairResult RunEurocPair(const std::filesystem::path& root, int pair,
                                    bool stereo = false, bool planar_alternatives = true) {
  const CameraIntrinsics k = EurocIntrinsics(0);
  const std::vector<Rigid3d> gt = {
      EurocCam(0.338337, 0.608466, -0.535476, 0.478082, 1.573832, 2.023348, 1.738755),
      EurocCam(0.478634, 0.415595, -0.700197, 0.328505, 1.872115, 1.786064, 1.586159),
      EurocCam(0.3394, -0.672895, -0.492724, -0.435018, -0.662997, -0.495046, 1.347300),
      EurocCam(0.39266, -0.590667, -0.58023, -0.400326, -0.345638, -0.501712, 1.320441)};
  const int m = 2 * pair, q = 2 * pair + 1;
  LoopDetector::Options options;  // defaults, except: two images are no trajectory to search
  options.search.strategy = SearchStrategy::kGlobal;
  options.search.exclude_recent = 0;
  options.min_path_ratio = 0;
  options.planar_alternatives = planar_alternatives;
  LoopDetector detector(options);
  EurocPairResult out;
  for (int i : {m, q}) {
    KeyframeInput in;
    in.id = i;
    in.timestamp = static_cast<double>(in.id);  // keyframe timestamps must increase
    in.image = EurocImage(root, "left", i);
    in.intrinsics = k;
    in.world_from_cam = Sim3d(gt[i]);
    if (stereo) {
      StereoPoints points = EurocStereoPoints(root, i);
      in.mapped_pixels = std::move(points.pixels);
      in.mapped_depths = std::move(points.depths);
    }
    out.result = detector.Process(in);
  }
  const Rigid3d rel = gt[m].Inverse() * gt[q];
  out.rotation_error_deg =
      RotationAngle(rel.rotation, out.result.match_from_query.rotation) * 180.0 / M_PI;
  out.baseline_m = rel.translation.norm();
  const Eigen::Vector3d t = out.result.match_from_query.translation;
  out.translation_direction_error_deg =
      t.norm() > 0
          ? std::acos(std::clamp(t.normalized().dot(rel.translation.normalized()), -1.0, 1.0)) *
                180.0 / M_PI
          : 180.0;
  if (out.result.pose_kind == RelativePoseKind::kSE3Metric ||
      out.result.pose_kind == RelativePoseKind::kSim3) {
    out.translation_error_m = (out.result.match_from_query.translation - rel.translation).norm();
  }
  return out;
}

}  // namespace sparseloop::test
