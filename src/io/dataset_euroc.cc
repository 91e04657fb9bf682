// The "euroc:DIR" loader (mav0/cam0/data.csv and sensor.yaml, optional
// mav0/state_groundtruth_estimate0/data.csv) and the sensor.yaml camera reader.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "io/dataset_internal.h"
#include "io/text_parsing.h"
#include "io/yaml_subset.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/rigid3.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop {

namespace fs = std::filesystem;
using io_internal::ParseInt64;
using io_internal::ParseYamlSubset;
using io_internal::Quote;
using io_internal::SplitComma;
using io_internal::TextFile;
using io_internal::YamlNumbers;

EurocCameraInfo ReadEurocSensorYaml(const fs::path& path) {
  const TextFile file(path);
  const auto yaml = ParseYamlSubset(file);
  const std::string& name = file.name();
  auto line_of = [&yaml](const std::string& key) {
    auto it = yaml.find(key);
    return it == yaml.end() ? 0 : it->second.line;
  };
  EurocCameraInfo info;
  if (auto it = yaml.find("camera_model"); it != yaml.end() && it->second.text != "pinhole") {
    throw FileError(name, it->second.line, "camera_model: pinhole", Quote(it->second.text));
  }
  const auto k = YamlNumbers(yaml, "intrinsics", name);
  if (k.size() != 4) {
    throw FileError(name, line_of("intrinsics"), "4 intrinsics [fu, fv, cu, cv]",
                    fmt::format("{} numbers", k.size()));
  }
  info.intrinsics.fx = k[0];
  info.intrinsics.fy = k[1];
  info.intrinsics.cx = k[2];
  info.intrinsics.cy = k[3];
  const auto res = YamlNumbers(yaml, "resolution", name);
  if (res.size() != 2 || res[0] <= 0 || res[1] <= 0 || res[0] != std::floor(res[0]) ||
      res[1] != std::floor(res[1])) {
    throw FileError(name, line_of("resolution"), "resolution [width, height] (positive integers)",
                    fmt::format("{} numbers", res.size()));
  }
  info.intrinsics.width = static_cast<int>(res[0]);
  info.intrinsics.height = static_cast<int>(res[1]);
  std::string model = "none";
  const bool has_model = yaml.count("distortion_model") > 0;
  if (has_model) model = yaml.at("distortion_model").text;
  size_t expected = 0;
  if (model == "radial-tangential" || model == "radtan") {
    info.intrinsics.distortion_model = DistortionModel::kRadialTangential;
    expected = 4;
  } else if (model == "equidistant") {
    info.intrinsics.distortion_model = DistortionModel::kEquidistant;
    expected = 4;
  } else if (model != "none") {
    throw FileError(name, line_of("distortion_model"),
                    "distortion_model radial-tangential, radtan, equidistant or none",
                    Quote(model));
  }
  if (expected > 0) {
    info.intrinsics.distortion = YamlNumbers(yaml, "distortion_coefficients", name);
    const size_t n = info.intrinsics.distortion.size();
    const bool ok =
        n == expected ||
        (info.intrinsics.distortion_model == DistortionModel::kRadialTangential && n == 5);
    if (!ok) {
      throw FileError(name, line_of("distortion_coefficients"),
                      fmt::format("{} distortion coefficients for {}", expected, model),
                      fmt::format("{}", n));
    }
    try {
      info.intrinsics.CheckDistortion();
    } catch (const std::invalid_argument& e) {
      throw FileError(name, line_of("distortion_coefficients"), "sane distortion_coefficients",
                      e.what());
    }
  } else if (yaml.count("distortion_coefficients")) {
    // Coefficients without a model would be ignored: the images would be used as if undistorted.
    const auto d = YamlNumbers(yaml, "distortion_coefficients", name);
    if (std::any_of(d.begin(), d.end(), [](double v) { return v != 0.0; })) {
      throw FileError(name, line_of("distortion_coefficients"),
                      "a distortion_model (radial-tangential or equidistant) for non-zero "
                      "distortion_coefficients",
                      has_model ? "distortion_model none" : "no distortion_model");
    }
  }
  try {
    info.intrinsics.Check();
  } catch (const std::invalid_argument& e) {
    throw FileError(name, line_of("intrinsics"), "valid intrinsics", e.what());
  }
  if (yaml.count("T_BS.data")) {
    const auto t = YamlNumbers(yaml, "T_BS.data", name);
    const int line = line_of("T_BS.data");
    if (t.size() != 16) {
      throw FileError(name, line, "16 numbers in T_BS data", fmt::format("{}", t.size()));
    }
    if (t[12] != 0 || t[13] != 0 || t[14] != 0 || t[15] != 1) {
      throw FileError(name, line, "last row 0 0 0 1 in T_BS", "other values");
    }
    Matrix3x4d m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = t[4 * r + c];
    try {
      info.body_from_cam = Rigid3d::FromMatrix3x4(m, kRotationTolerance);
    } catch (const std::invalid_argument& e) {
      throw FileError(name, line, "a rotation in T_BS", e.what());
    }
  }
  return info;
}

namespace io_internal {

Dataset OpenEuroc(const fs::path& root, const DatasetOptions& options) {
  Dataset d;
  d.kind = "euroc";
  d.root = root;
  const fs::path cam = root / "mav0" / "cam0";
  RequireDirectory(cam, "an EuRoC camera folder mav0/cam0/");
  const fs::path csv = cam / "data.csv";
  RequireFile(csv, "an EuRoC image list mav0/cam0/data.csv");
  const TextFile file(csv);
  int64_t previous_ns = 0;
  for (const auto& line : file.DataLines()) {
    const auto t = SplitComma(line.text);
    if (t.size() != 2) {
      throw FileError(file.name(), line.number,
                      "2 comma-separated columns (timestamp [ns],filename)",
                      fmt::format("{} columns", t.size()));
    }
    const int64_t ns = ParseInt64(t[0], file.name(), line.number, "timestamp [ns]");
    if (!d.frames.empty() && ns <= previous_ns) {
      throw FileError(file.name(), line.number,
                      fmt::format("a timestamp greater than the previous one ({} ns)", previous_ns),
                      fmt::format("{} ns", ns));
    }
    previous_ns = ns;
    const double seconds =
        static_cast<double>(ns / 1000000000) + static_cast<double>(ns % 1000000000) * 1e-9;
    d.frames.push_back(DatasetFrame{static_cast<int64_t>(d.frames.size()), seconds,
                                    cam / "data" / std::string(t[1]), std::nullopt});
  }
  if (d.frames.empty()) throw FileError(file.name(), 0, "at least one image line", "none");

  std::optional<Rigid3d> body_from_cam;
  const fs::path yaml = cam / "sensor.yaml";
  if (options.intrinsics) {
    d.intrinsics = *options.intrinsics;
    d.intrinsics_source = options.intrinsics_name;
    std::error_code ec;
    if (fs::is_regular_file(yaml, ec)) {
      const EurocCameraInfo info = ReadEurocSensorYaml(yaml);
      body_from_cam = info.body_from_cam;
      const auto& k = info.intrinsics.distortion;
      if (std::any_of(k.begin(), k.end(), [](double v) { return v != 0.0; }) &&
          d.intrinsics.distortion_model == DistortionModel::kNone) {
        Logger().warn(
            "{}: its {} distortion is not used: {} replaces the camera and has none, so the "
            "images are taken as undistorted (leave {} out to use sensor.yaml)",
            yaml.string(), ToString(info.intrinsics.distortion_model), options.intrinsics_name,
            options.intrinsics_name);
      }
    }
  } else {
    RequireFile(yaml,
                fmt::format("an EuRoC mav0/cam0/sensor.yaml (or {})", options.intrinsics_name));
    const EurocCameraInfo info = ReadEurocSensorYaml(yaml);
    d.intrinsics = info.intrinsics;
    d.intrinsics_source = yaml.string();
    body_from_cam = info.body_from_cam;
  }
  const fs::path own_gt = root / "mav0" / "state_groundtruth_estimate0" / "data.csv";
  std::error_code ec;
  size_t attached = 0;
  if (!options.poses.empty()) {
    d.gt_path = options.poses;
    const Trajectory gt = ReadGtTrajectory(d.gt_path, TrajectoryFormat::kAuto);
    attached = gt.has_timestamps ? AttachGtByTime(d.frames, gt, options.euroc_max_dt)
                                 : AttachByIndex(d.frames, gt);
  } else if (fs::is_regular_file(own_gt, ec)) {
    d.gt_path = own_gt;
    const Trajectory gt = ReadGtTrajectory(own_gt, TrajectoryFormat::kEuroc);
    attached = AttachGtByTime(d.frames, gt, options.euroc_max_dt);
    if (options.euroc_gt_in_camera_frame) {
      if (!body_from_cam) {
        throw FileError(yaml.string(), 0, "T_BS (needed to express the body GT in the camera)",
                        "none");
      }
      for (auto& f : d.frames) {
        if (f.gt_world_from_cam) f.gt_world_from_cam = *f.gt_world_from_cam * *body_from_cam;
      }
    }
  }
  LogGt(d, attached);
  return d;
}

}  // namespace io_internal

}  // namespace sparseloop
