// The "tum:DIR" loader (rgb.txt, optional groundtruth.txt) and the TUM RGB-D Kinect intrinsics.
#include <stdexcept>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "io/dataset_internal.h"
#include "io/text_parsing.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

namespace fs = std::filesystem;
using io_internal::ParseDouble;
using io_internal::SplitWhitespace;
using io_internal::TextFile;

CameraIntrinsics TumFreiburgIntrinsics(int freiburg) {
  // https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats (ROS default for fr3).
  CameraIntrinsics k;
  k.width = 640;
  k.height = 480;
  switch (freiburg) {
    case 1:
      k.fx = 517.3, k.fy = 516.5, k.cx = 318.6, k.cy = 255.3;
      k.distortion_model = DistortionModel::kRadialTangential;
      k.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
      break;
    case 2:
      k.fx = 520.9, k.fy = 521.0, k.cx = 325.1, k.cy = 249.7;
      k.distortion_model = DistortionModel::kRadialTangential;
      k.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
      break;
    case 3:
      k.fx = 535.4, k.fy = 539.2, k.cx = 320.1, k.cy = 247.6;
      break;
    default:
      SL_CHECK_MSG(false, "TUM freiburg camera must be 1, 2 or 3, got {}", freiburg);
  }
  return k;
}

namespace io_internal {

Dataset OpenTum(const fs::path& root, const DatasetOptions& options) {
  Dataset d;
  d.kind = "tum";
  d.root = root;
  const fs::path rgb = root / "rgb.txt";
  RequireFile(rgb, "a TUM rgb.txt");
  const TextFile file(rgb);
  for (const auto& line : file.DataLines()) {
    const auto t = SplitWhitespace(line.text);
    if (t.size() != 2) {
      throw FileError(file.name(), line.number, "2 columns (timestamp filename)",
                      fmt::format("{} columns", t.size()));
    }
    const double time = ParseDouble(t[0], file.name(), line.number, "timestamp");
    if (!d.frames.empty() && !(time > d.frames.back().timestamp)) {
      throw FileError(file.name(), line.number,
                      fmt::format("a timestamp greater than the previous one ({:.6f})",
                                  d.frames.back().timestamp),
                      fmt::format("{:.6f}", time));
    }
    d.frames.push_back(DatasetFrame{static_cast<int64_t>(d.frames.size()), time,
                                    root / std::string(t[1]), std::nullopt});
  }
  if (d.frames.empty()) throw FileError(file.name(), 0, "at least one image line", "none");

  if (options.intrinsics) {
    d.intrinsics = *options.intrinsics;
    d.intrinsics_source = options.intrinsics_name;
  } else {
    const std::string name = ToLower(root.filename().string());
    int freiburg = 0;
    for (int i = 1; i <= 3; ++i) {
      if (name.find(fmt::format("freiburg{}", i)) != std::string::npos ||
          name.find(fmt::format("fr{}", i)) != std::string::npos) {
        freiburg = i;
        break;
      }
    }
    if (freiburg == 0) {
      throw std::invalid_argument(
          fmt::format("tum:{}: intrinsics are needed ({}) because the folder name names none of "
                      "freiburg1/2/3 (fr1/fr2/fr3)",
                      root.string(), options.intrinsics_name));
    }
    d.intrinsics = TumFreiburgIntrinsics(freiburg);
    d.intrinsics_source = fmt::format("the TUM freiburg{} intrinsics", freiburg);
  }
  const fs::path own_gt = root / "groundtruth.txt";
  std::error_code ec;
  d.gt_path = !options.poses.empty()            ? options.poses
              : fs::is_regular_file(own_gt, ec) ? own_gt
                                                : fs::path();
  size_t attached = 0;
  if (!d.gt_path.empty()) {
    const Trajectory gt = ReadGtTrajectory(d.gt_path, TrajectoryFormat::kAuto);
    attached = gt.has_timestamps ? AttachGtByTime(d.frames, gt, options.tum_max_dt)
                                 : AttachByIndex(d.frames, gt);
  }
  LogGt(d, attached);
  return d;
}

}  // namespace io_internal

}  // namespace sparseloop
