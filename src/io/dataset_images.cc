// The "images:DIR" loader: the folder's images in natural order, intrinsics from the options,
// poses (by frame index) optional.
#include <stdexcept>

#include <fmt/format.h>

#include "io/dataset_internal.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"

namespace sparseloop::io_internal {

namespace fs = std::filesystem;

Dataset OpenImages(const fs::path& root, const DatasetOptions& options) {
  if (!options.intrinsics) {
    throw std::invalid_argument(
        fmt::format("images:{} needs {} (an image folder has no calibration)", root.string(),
                    options.intrinsics_name));
  }
  Dataset d;
  d.kind = "images";
  d.root = root;
  d.intrinsics = *options.intrinsics;
  d.intrinsics_source = options.intrinsics_name;
  const auto images = ListFiles(root, {".png", ".jpg", ".jpeg", ".pgm", ".bmp"});
  if (images.empty()) {
    throw FileError(root.string(), 0, "at least one image (png, jpg, jpeg, pgm, bmp)", "none");
  }
  for (size_t i = 0; i < images.size(); ++i) {
    d.frames.push_back(
        DatasetFrame{static_cast<int64_t>(i), static_cast<double>(i), images[i], std::nullopt});
  }
  size_t attached = 0;
  if (!options.poses.empty()) {
    d.gt_path = options.poses;
    attached = AttachByIndex(d.frames, ReadGtTrajectory(d.gt_path, TrajectoryFormat::kAuto));
    if (attached < d.frames.size()) {
      Logger().warn("images:{}: {} of {} frames have no pose in {}", root.string(),
                    d.frames.size() - attached, d.frames.size(), d.gt_path.string());
    }
  }
  LogGt(d, attached);
  return d;
}

}  // namespace sparseloop::io_internal
