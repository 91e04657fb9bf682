#pragma once
// Small real-data readers for the detector tests and the accuracy programs in bench/ (kept out of
// the library: its io module owns the general dataset readers). Missing files throw
// std::runtime_error naming them.
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "data_dir.h"
#include "sparseloop/core/camera.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/synthetic/worlds.h"

namespace sparseloop::test {

struct Frame {
  cv::Mat image;
  CameraIntrinsics intrinsics;
  Rigid3d world_from_cam;
  bool has_pose = false;
};

// Strecha .camera: K (3x3), 3 zeros, R (3x3), camera centre (3), width height.
// world_from_cam = [R | c] (transpose = false) or [R^T | c]; the castle test checks which one
// agrees with the essential matrices of the images.
inline Frame ReadStrechaCamera(const std::filesystem::path& camera_file, bool transpose) {
  std::ifstream in(camera_file);
  double v[26];
  for (double& x : v) in >> x;
  if (!in) throw std::runtime_error("cannot read the Strecha camera " + camera_file.string());
  Frame f;
  f.intrinsics.fx = v[0];
  f.intrinsics.cx = v[2];
  f.intrinsics.fy = v[4];
  f.intrinsics.cy = v[5];
  f.intrinsics.width = static_cast<int>(v[24]);
  f.intrinsics.height = static_cast<int>(v[25]);
  Eigen::Matrix3d r;
  r << v[12], v[13], v[14], v[15], v[16], v[17], v[18], v[19], v[20];
  if (transpose) r.transposeInPlace();
  f.world_from_cam = Rigid3d(Eigen::Quaterniond(r), Eigen::Vector3d(v[21], v[22], v[23]));
  f.has_pose = true;
  return f;
}

// Views 0001..0029 of castle_p30_768 (`root`; empty: DataDir()/castle_p30_768).
inline std::vector<Frame> LoadCastle(bool transpose = false, std::filesystem::path root = {}) {
  if (root.empty()) root = DataDir() / "castle_p30_768";
  std::vector<Frame> frames;
  for (int i = 1; i <= 29; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%04d.jpg", i);
    Frame f =
        ReadStrechaCamera(root / "gt_dense_cameras" / (std::string(name) + ".camera"), transpose);
    f.image = cv::imread((root / "images" / name).string(), cv::IMREAD_GRAYSCALE);
    if (f.image.empty())
      throw std::runtime_error("cannot read the castle image " + std::string(name));
    frames.push_back(std::move(f));
  }
  return frames;
}

inline std::vector<Rigid3d> ReadKittiPoses(const std::filesystem::path& path) {
  std::vector<Rigid3d> poses;
  std::ifstream in(path);
  Matrix3x4d m;
  while (true) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) in >> m(r, c);
    if (!in) break;
    poses.push_back(Rigid3d::FromMatrix3x4(m, 1e-3));
  }
  return poses;
}

// KITTI 04-12 cam0 (kitti07_first160), from the one table in the synthetic module.
inline CameraIntrinsics KittiIntrinsics() { return synthetic::KittiCam0Intrinsics(7); }

inline std::vector<cv::Mat> LoadKittiImages(int count) {
  std::vector<cv::Mat> images;
  for (int i = 0; i < count; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    images.push_back(cv::imread((DataDir() / "kitti07_first160" / "image_0" / name).string(),
                                cv::IMREAD_GRAYSCALE));
  }
  return images;
}

// The rtabmap camera is unknown: fx = fy = 0.9 * width (about 58 deg horizontal field of view,
// a typical webcam), principal point at the image centre.
inline CameraIntrinsics GuessIntrinsics(int width, int height) {
  CameraIntrinsics k;
  k.fx = k.fy = 0.9 * width;
  k.cx = 0.5 * width;
  k.cy = 0.5 * height;
  k.width = width;
  k.height = height;
  return k;
}

inline std::vector<cv::Mat> LoadRtabmap() {
  std::vector<cv::Mat> images;
  for (int i = 1; i <= 84; ++i)
    images.push_back(cv::imread(
        (DataDir() / "rtabmap_corridor_loop" / "samples" / (std::to_string(i) + ".jpg")).string(),
        cv::IMREAD_GRAYSCALE));
  return images;
}

// 0-based (query, match) pairs from the 1-based GT list.
inline std::vector<std::pair<int, int>> LoadRtabmapGt() {
  std::vector<std::pair<int, int>> gt;
  std::ifstream in(DataDir() / "rtabmap_corridor_loop" / "gt_loops_from_bmp.txt");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    int q, m;
    if (std::sscanf(line.c_str(), "%d %d", &q, &m) == 2) gt.emplace_back(q - 1, m - 1);
  }
  return gt;
}

}  // namespace sparseloop::test
