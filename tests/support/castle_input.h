#pragma once
// The castle views as detector input (test::LoadCastle: view i + 1 with its exact pose as the raw
// pose, id and timestamp the view number), and the castle ring family: all 30 views as a dataset
// with their exact poses, and raw poses drifted from them as a monocular vSLAM would.
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "real_data.h"
#include "sparseloop/core/trajectory.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/loop/loop_detector.h"

namespace sparseloop::test {

inline KeyframeInput CastleKeyframe(const std::vector<Frame>& frames, size_t i) {
  KeyframeInput in;
  in.id = static_cast<int64_t>(i + 1);        // view number
  in.timestamp = static_cast<double>(in.id);  // keyframe timestamps must increase
  in.image = frames[i].image;
  in.intrinsics = frames[i].intrinsics;
  in.world_from_cam = Sim3d(frames[i].world_from_cam);
  return in;
}

// castle_p30_768's views 0000..0029 as an images dataset (no depths) and their exact poses
// (frame = timestamp = view number). `root` empty: DataDir()/castle_p30_768.
struct CastleRing {
  Dataset dataset;
  Trajectory gt;
};
inline CastleRing LoadCastleRing(std::filesystem::path root = {}) {
  if (root.empty()) root = DataDir() / "castle_p30_768";
  CastleRing c;
  c.dataset.kind = "images";
  c.dataset.root = root / "images";
  c.gt.has_rotation = true;
  for (int i = 0; i < 30; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%04d.jpg", i);
    const Frame f =
        ReadStrechaCamera(root / "gt_dense_cameras" / (std::string(name) + ".camera"), false);
    if (i == 0) c.dataset.intrinsics = f.intrinsics;
    DatasetFrame frame;
    frame.index = i;
    frame.timestamp = i;
    frame.image_path = root / "images" / name;
    c.dataset.frames.push_back(frame);
    StampedPose p;
    p.frame = i;
    p.timestamp = i;
    p.world_from_cam = f.world_from_cam;
    c.gt.poses.push_back(p);
  }
  return c;
}

// Monocular drift of the castle ring's raw poses, per keyframe: every raw step is the GT step
// rotated by `bias_deg` (a rotation vector in the camera frame: x pitch, y yaw / heading, z roll
// about the optical axis) and its length multiplied by scale_step^i, plus seeded noise.
struct CastleDrift {
  Eigen::Vector3d bias_deg = Eigen::Vector3d::Zero();  // degrees per keyframe, camera x, y, z
  double scale_step = 1.0;  // each raw step length is multiplied by scale_step^i
  uint64_t seed = 0;        // per-step noise: 0.1 deg rotation, 1 % translation (0 = none)
};

// The raw trajectory: chained from the exact first pose, step i is
// [R_gt * Exp(bias) * noise_R | scale_step^i * t_gt + noise_t].
inline Trajectory DriftCastle(const Trajectory& gt, const CastleDrift& spec) {
  std::mt19937_64 rng(spec.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const double angle_deg = spec.bias_deg.norm();
  const Eigen::Quaterniond bias = angle_deg > 0.0
                                      ? Eigen::Quaterniond(Eigen::AngleAxisd(
                                            angle_deg * M_PI / 180.0, spec.bias_deg / angle_deg))
                                      : Eigen::Quaterniond::Identity();
  Trajectory raw = gt;
  Rigid3d pose = gt.poses[0].world_from_cam;
  for (size_t i = 1; i < gt.poses.size(); ++i) {
    const Rigid3d& a = gt.poses[i - 1].world_from_cam;
    const Rigid3d& b = gt.poses[i].world_from_cam;
    Eigen::Quaterniond step_r = a.rotation.conjugate() * b.rotation * bias;
    Eigen::Vector3d step_t = a.rotation.conjugate() * (b.translation - a.translation);
    step_t *= std::pow(spec.scale_step, static_cast<double>(i));
    if (spec.seed != 0) {
      const Eigen::Vector3d w(n01(rng), n01(rng), n01(rng));
      step_r = step_r *
               Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * M_PI / 180.0 * w.norm(), w.normalized()));
      step_t += 0.01 * step_t.norm() * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
    }
    pose = Rigid3d(pose.rotation * step_r, pose.translation + pose.rotation * step_t);
    pose.rotation.normalize();
    raw.poses[i].world_from_cam = pose;
  }
  return raw;
}

}  // namespace sparseloop::test
