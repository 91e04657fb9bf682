// The "kitti:DIR" loader: image_0/NNNNNN.png, times.txt, calib.txt (P0) and the optional pose
// file (docs/FORMATS.md).
#include <algorithm>
#include <array>
#include <string>
#include <system_error>
#include <vector>

#include <fmt/format.h>

#include "io/dataset_internal.h"
#include "io/text_parsing.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

namespace fs = std::filesystem;
using io_internal::ListFiles;
using io_internal::ParseDouble;
using io_internal::SplitWhitespace;
using io_internal::TextFile;

namespace {

CameraIntrinsics ReadKittiCalibP0(const fs::path& path) {
  const TextFile file(path);
  for (const auto& line : file.DataLines()) {
    const auto t = SplitWhitespace(line.text);
    if (t.empty() || t[0] != "P0:") continue;
    if (t.size() != 13) {
      throw FileError(file.name(), line.number, "'P0:' followed by 12 numbers",
                      fmt::format("{} numbers", t.size() - 1));
    }
    std::array<double, 12> p{};
    for (size_t i = 0; i < 12; ++i) {
      p[i] = ParseDouble(t[i + 1], file.name(), line.number, fmt::format("P0[{}]", i));
    }
    CameraIntrinsics k;
    k.fx = p[0];
    k.cx = p[2];
    k.fy = p[5];
    k.cy = p[6];
    if (!(k.fx > 0 && k.fy > 0)) {
      throw FileError(file.name(), line.number, "positive focal lengths in P0",
                      fmt::format("fx={} fy={}", k.fx, k.fy));
    }
    return k;
  }
  throw FileError(file.name(), 0, "a line 'P0: <12 numbers>'", "none");
}

std::vector<double> ReadKittiTimes(const fs::path& path) {
  const TextFile file(path);
  std::vector<double> times;
  for (const auto& line : file.DataLines()) {
    const auto t = SplitWhitespace(line.text);
    if (t.size() != 1) {
      throw FileError(file.name(), line.number, "1 column (time in seconds)",
                      fmt::format("{} columns", t.size()));
    }
    const double v = ParseDouble(t[0], file.name(), line.number, "time");
    if (!times.empty() && !(v > times.back())) {
      throw FileError(file.name(), line.number,
                      fmt::format("a time greater than the previous one ({})", times.back()),
                      fmt::format("{}", v));
    }
    times.push_back(v);
  }
  return times;
}

// The pose file of a KITTI folder; see docs/FORMATS.md "kitti:DIR" for the rule.
fs::path FindKittiPoses(const fs::path& dir, size_t frame_count) {
  const fs::path poses = dir / "poses.txt";
  std::error_code ec;
  if (fs::is_regular_file(poses, ec)) return poses;
  const fs::path seq = dir / (dir.filename().string() + ".txt");
  if (fs::is_regular_file(seq, ec)) return seq;
  for (const auto& candidate : ListFiles(dir, {".txt"})) {
    const std::string name = candidate.filename().string();
    if (name == "times.txt" || name == "calib.txt") continue;
    try {
      const TextFile file(candidate);
      const auto lines = file.DataLines();
      if (lines.size() == frame_count && SplitWhitespace(lines.front().text).size() == 12) {
        return candidate;
      }
    } catch (const FileError&) {
      continue;
    }
  }
  return {};
}

}  // namespace

namespace io_internal {

Dataset OpenKitti(const fs::path& root, const DatasetOptions& options) {
  Dataset d;
  d.kind = "kitti";
  d.root = root;
  const fs::path image_dir = root / "image_0";
  RequireDirectory(image_dir, "a KITTI image folder image_0/");
  const auto images = ListFiles(image_dir, {".png"});
  if (images.empty()) throw FileError(image_dir.string(), 0, "at least one .png image", "none");
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string stem = images[i].stem().string();
    if (!io_internal::LooksLikeInteger(stem) || std::stoll(stem) != static_cast<long long>(i)) {
      throw FileError(images[i].string(), 0,
                      fmt::format("images numbered consecutively from 000000 (number {})", i),
                      images[i].filename().string());
    }
  }
  const fs::path times_path = root / "times.txt";
  RequireFile(times_path, "a KITTI times.txt");
  const auto times = ReadKittiTimes(times_path);
  if (times.size() < images.size()) {
    throw FileError(times_path.string(), 0,
                    fmt::format("at least {} times (one per image)", images.size()),
                    fmt::format("{}", times.size()));
  }
  if (options.intrinsics) {
    d.intrinsics = *options.intrinsics;
    d.intrinsics_source = options.intrinsics_name;
  } else {
    const fs::path calib = root / "calib.txt";
    RequireFile(calib, fmt::format("a KITTI calib.txt (or {})", options.intrinsics_name));
    d.intrinsics = ReadKittiCalibP0(calib);
    d.intrinsics_source = calib.string();  // width and height: from the first image
  }
  for (size_t i = 0; i < images.size(); ++i) {
    d.frames.push_back(DatasetFrame{static_cast<int64_t>(i), times[i], images[i], std::nullopt});
  }
  d.gt_path = options.poses.empty() ? FindKittiPoses(root, images.size()) : options.poses;
  size_t attached = 0;
  if (!d.gt_path.empty()) {
    const Trajectory gt = ReadGtTrajectory(d.gt_path, TrajectoryFormat::kAuto);
    attached = AttachByIndex(d.frames, gt);
    if (attached != d.frames.size()) {
      const auto missing = std::find_if(d.frames.begin(), d.frames.end(), [](const auto& f) {
        return !f.gt_world_from_cam.has_value();
      });
      throw FileError(d.gt_path.string(), 0,
                      fmt::format("a pose for each of the {} images", d.frames.size()),
                      fmt::format("no pose for frame {}", missing->index));
    }
  }
  LogGt(d, attached);
  return d;
}

}  // namespace io_internal

}  // namespace sparseloop
