// Datasets: Dataset and DatasetOptions, OpenDataset (the spec, the dispatch to the loaders of
// dataset_kitti.cc, dataset_tum.cc, dataset_euroc.cc and dataset_images.cc, the image checks), the
// nearest-time GT association, and the helpers the loaders share (dataset_internal.h).
#include "sparseloop/io/dataset.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string_view>
#include <system_error>

#include <fmt/format.h>

#include "io/dataset_internal.h"
#include "io/image_header.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/time_association.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop {

namespace fs = std::filesystem;
using io_internal::IsJpeg;
using io_internal::JpegEndsWithEoi;
using io_internal::OpenEuroc;
using io_internal::OpenImages;
using io_internal::OpenKitti;
using io_internal::OpenTum;
using io_internal::RequireDirectory;

bool Dataset::has_gt() const {
  return std::any_of(frames.begin(), frames.end(),
                     [](const DatasetFrame& f) { return f.gt_world_from_cam.has_value(); });
}

Trajectory Dataset::GtTrajectory() const {
  Trajectory traj;
  traj.has_rotation = true;
  traj.has_timestamps = kind != "images";
  for (const auto& f : frames) {
    if (!f.gt_world_from_cam) continue;
    traj.poses.push_back(StampedPose{f.timestamp, f.index, *f.gt_world_from_cam});
  }
  return traj;
}

void DatasetOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(tum_max_dt) && tum_max_dt > 0.0,
               "DatasetOptions::tum_max_dt must be positive, got {}", tum_max_dt);
  SL_CHECK_MSG(std::isfinite(euroc_max_dt) && euroc_max_dt > 0.0,
               "DatasetOptions::euroc_max_dt must be positive, got {}", euroc_max_dt);
  SL_CHECK_MSG(std::isfinite(rosbag_max_dt) && rosbag_max_dt > 0.0,
               "DatasetOptions::rosbag_max_dt must be positive, got {}", rosbag_max_dt);
  if (intrinsics) intrinsics->Check();
}

size_t AttachGtByTime(std::vector<DatasetFrame>& frames, const Trajectory& gt, double max_dt) {
  std::vector<double> frame_times, gt_times;
  for (const auto& f : frames) frame_times.push_back(f.timestamp);
  for (const auto& p : gt.poses) gt_times.push_back(p.timestamp);
  const auto rows = AssociateInTime(frame_times, gt_times, max_dt, TimePairing::kNearest);
  size_t attached = 0;
  for (size_t k = 0; k < frames.size(); ++k) {
    if (rows[k]) {
      frames[k].gt_world_from_cam = gt.poses[*rows[k]].world_from_cam;
      ++attached;
    }
  }
  return attached;
}

namespace {

// Natural order: digit runs compare numerically ("2.png" < "10.png"), the rest bytewise.
bool NaturalLess(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) &&
        std::isdigit(static_cast<unsigned char>(b[j]))) {
      size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      std::string_view da(a.data() + i, ie - i), db(b.data() + j, je - j);
      while (da.size() > 1 && da.front() == '0') da.remove_prefix(1);
      while (db.size() > 1 && db.front() == '0') db.remove_prefix(1);
      if (da.size() != db.size()) return da.size() < db.size();
      if (da != db) return da < db;
      if (ie - i != je - j) return ie - i < je - j;  // fewer leading zeros first
      i = ie, j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i, ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

}  // namespace

namespace io_internal {

std::string ToLower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::vector<fs::path> ListFiles(const fs::path& dir, const std::vector<std::string>& extensions) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string ext = ToLower(entry.path().extension().string());
    if (std::find(extensions.begin(), extensions.end(), ext) == extensions.end()) continue;
    std::error_code status_ec;
    const bool regular = entry.is_regular_file(status_ec);
    // A link that loops or points nowhere, named as an image: the user meant it as one.
    if (status_ec) {
      throw FileError(entry.path().string(), 0, "an image file or a link to one",
                      status_ec.message());
    }
    if (regular) files.push_back(entry.path());
  }
  if (ec) throw FileError(dir.string(), 0, "a readable directory", ec.message());
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    return NaturalLess(a.filename().string(), b.filename().string());
  });
  return files;
}

namespace {

// What `path` is, for a message: "missing", "a regular file", "a directory", or why its status
// cannot be read ("Too many levels of symbolic links", "Permission denied").
std::string WhatIsThere(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found) return "missing";
  if (ec) return ec.message();
  switch (status.type()) {
    case fs::file_type::regular:
      return "a regular file";
    case fs::file_type::directory:
      return "a directory";
    default:
      return "neither a file nor a directory";
  }
}

}  // namespace

void RequireDirectory(const fs::path& dir, const std::string& what) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw FileError(dir.string(), 0, what, WhatIsThere(dir));
}

void RequireFile(const fs::path& file, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw FileError(file.string(), 0, what, WhatIsThere(file));
}

Trajectory ReadGtTrajectory(const fs::path& path, TrajectoryFormat format) {
  Trajectory traj = ReadTrajectory(path, format);
  if (!traj.has_rotation) {
    throw FileError(path.string(), 0, "a ground-truth trajectory with orientations",
                    "a positions-only file");
  }
  return traj;
}

// Frame i gets the pose whose frame index is i. Returns how many frames got one.
size_t AttachByIndex(std::vector<DatasetFrame>& frames, const Trajectory& gt) {
  std::map<int64_t, const StampedPose*> by_frame;
  for (const auto& p : gt.poses) by_frame[p.frame] = &p;
  size_t attached = 0;
  for (auto& f : frames) {
    auto it = by_frame.find(f.index);
    if (it == by_frame.end()) continue;
    f.gt_world_from_cam = it->second->world_from_cam;
    ++attached;
  }
  return attached;
}

void LogGt(const Dataset& d, size_t attached) {
  Logger().info("{} dataset {}: {} frames, ground truth for {} from {}", d.kind, d.root.string(),
                d.frames.size(), attached, d.gt_path.empty() ? "(none)" : d.gt_path.string());
}

}  // namespace io_internal

namespace {

// The image checks of OpenDataset (dataset.h): sizes from the headers, against the intrinsics'
// size or the first image's; truncated JPEGs; the principal point inside the image.
void CheckImages(Dataset& d) {
  std::optional<ImageSize> reference;
  std::string reference_source;
  if (d.intrinsics.width > 0 && d.intrinsics.height > 0) {
    reference = ImageSize{d.intrinsics.width, d.intrinsics.height};
    reference_source = d.intrinsics_source;
  }
  for (const DatasetFrame& frame : d.frames) {
    const std::optional<ImageSize> size = ReadImageSize(frame.image_path);
    if (!size) continue;  // unreadable header: the decoder decides (run skips such frames)
    const std::string name = frame.image_path.string();
    const std::string got = fmt::format("{}x{}", size->width, size->height);
    if (size->width < kMinImageSide || size->height < kMinImageSide) {
      throw FileError(name, 0,
                      fmt::format("an image of at least {0}x{0} pixels (ORB needs a 31-pixel "
                                  "patch and an 8-level pyramid)",
                                  kMinImageSide),
                      got);
    }
    if (int64_t{size->width} * size->height > kMaxImagePixels) {
      throw FileError(name, 0, fmt::format("an image of at most {} pixels", kMaxImagePixels), got);
    }
    if (!reference) {
      reference = size;
      reference_source = name;
    } else if (size->width != reference->width || size->height != reference->height) {
      throw FileError(name, 0,
                      fmt::format("every image of the sequence {}x{} (the size of {})",
                                  reference->width, reference->height, reference_source),
                      got);
    }
    if (IsJpeg(frame.image_path) && !JpegEndsWithEoi(frame.image_path)) {
      throw FileError(name, 0, "a complete JPEG file (ending with the EOI marker FF D9)",
                      "a truncated file");
    }
  }
  if (reference && (d.intrinsics.width == 0 || d.intrinsics.height == 0)) {
    d.intrinsics.width = reference->width;
    d.intrinsics.height = reference->height;
  }
  const CameraIntrinsics& k = d.intrinsics;
  if (k.width > 0 && k.height > 0 && !(k.cx > 0 && k.cx < k.width && k.cy > 0 && k.cy < k.height)) {
    throw std::invalid_argument(fmt::format(
        "{}: principal point ({}, {}) outside the {}x{} image{}", d.intrinsics_source, k.cx, k.cy,
        k.width, k.height,
        reference_source == d.intrinsics_source ? "" : " (the size of " + reference_source + ")"));
  }
}

}  // namespace

Dataset OpenDataset(const std::string& spec, const DatasetOptions& options) {
  options.Check();
  const size_t colon = spec.find(':');
  SL_CHECK_MSG(colon != std::string::npos && colon + 1 < spec.size(),
               "dataset spec must be <kind>:<DIR> with kind kitti, tum, euroc or images, got '{}'",
               spec);
  const std::string kind = spec.substr(0, colon);
  fs::path root = fs::path(spec.substr(colon + 1)).lexically_normal();
  if (!root.has_filename() && root.has_parent_path()) root = root.parent_path();  // "DIR/"
  SL_CHECK_MSG(kind == "kitti" || kind == "tum" || kind == "euroc" || kind == "images",
               "unknown dataset kind '{}' in '{}' (valid: kitti, tum, euroc, images)", kind, spec);
  RequireDirectory(root, "an existing dataset folder");
  Dataset d = kind == "kitti"   ? OpenKitti(root, options)
              : kind == "tum"   ? OpenTum(root, options)
              : kind == "euroc" ? OpenEuroc(root, options)
                                : OpenImages(root, options);
  CheckImages(d);
  return d;
}

}  // namespace sparseloop
