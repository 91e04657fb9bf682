#pragma once
// Helpers for the eval tests: synthetic trajectories and minimal readers for the two real-data
// files the tests use (kept independent of the io module so that eval tests only need eval).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/sim3.h"
#include "sparseloop/core/trajectory.h"

namespace sparseloop::test {

// A closed, non-planar loop of n poses (figure-eight-like in x-z with a height wave), camera z axis
// along the direction of travel. Timestamps 0.1 s apart, frames 0..n-1.
inline Trajectory MakeLoopTrajectory(size_t n, double radius = 50.0) {
  Trajectory traj;
  for (size_t i = 0; i < n; ++i) {
    const double a = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n);
    const Eigen::Vector3d p(radius * std::sin(a), 3.0 * std::sin(3.0 * a),
                            radius * std::sin(a) * std::cos(a));
    const Eigen::Vector3d v(radius * std::cos(a), 9.0 * std::cos(3.0 * a),
                            radius * std::cos(2.0 * a));
    const Eigen::Vector3d z = v.normalized();
    Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d r;
    r << x, y, z;
    StampedPose pose;
    pose.frame = static_cast<int64_t>(i);
    pose.timestamp = 0.1 * static_cast<double>(i);
    pose.world_from_cam = Rigid3d(Eigen::Quaterniond(r), p);
    traj.poses.push_back(pose);
  }
  return traj;
}

inline Sim3d RandomSim3(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  const Eigen::Quaterniond q(Eigen::AngleAxisd(3.0 * u(rng), axis.normalized()));
  const double scale = std::exp(1.5 * u(rng));
  return Sim3d(scale, q, Eigen::Vector3d(100 * u(rng), 100 * u(rng), 100 * u(rng)));
}

// KITTI pose file: 12 numbers per line (3x4 row-major world_from_cam). Fails the test on error.
inline std::vector<Eigen::Matrix4d> ReadKittiMatrices(const std::filesystem::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::vector<Eigen::Matrix4d> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::istringstream ss(line);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) ss >> m(r, c);
    }
    EXPECT_FALSE(ss.fail()) << path << ": " << line;
    out.push_back(m);
  }
  return out;
}

inline Trajectory KittiTrajectory(const std::vector<Eigen::Matrix4d>& matrices) {
  Trajectory traj;
  traj.has_timestamps = false;
  for (size_t i = 0; i < matrices.size(); ++i) {
    StampedPose pose;
    pose.frame = static_cast<int64_t>(i);
    pose.timestamp = static_cast<double>(i);
    pose.world_from_cam = Rigid3d::FromMatrix3x4(matrices[i].topRows<3>(), 1e-3);
    traj.poses.push_back(pose);
  }
  return traj;
}

// "frame x y z ..." positions-only file (first 4 columns).
struct PositionsFile {
  std::vector<int64_t> frames;
  std::vector<Eigen::Vector3d> positions;
};
inline PositionsFile ReadPositions(const std::filesystem::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  PositionsFile out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    int64_t frame = 0;
    Eigen::Vector3d p;
    ss >> frame >> p.x() >> p.y() >> p.z();
    EXPECT_FALSE(ss.fail()) << path << ": " << line;
    out.frames.push_back(frame);
    out.positions.push_back(p);
  }
  return out;
}

inline Trajectory PositionsTrajectory(const PositionsFile& file) {
  Trajectory traj;
  traj.has_rotation = false;
  traj.has_timestamps = false;
  for (size_t i = 0; i < file.frames.size(); ++i) {
    StampedPose pose;
    pose.frame = file.frames[i];
    pose.timestamp = static_cast<double>(file.frames[i]);
    pose.world_from_cam.translation = file.positions[i];
    traj.poses.push_back(pose);
  }
  return traj;
}

}  // namespace sparseloop::test
