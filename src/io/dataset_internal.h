#pragma once
// Internal to io: what the dataset loaders share (dataset.cc: folder listing, required files,
// ground-truth reading and attaching by frame index, the summary log line) and the loaders
// OpenDataset dispatches to, one file per format (dataset_kitti.cc, dataset_tum.cc,
// dataset_euroc.cc, dataset_images.cc).
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "sparseloop/core/trajectory.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop::io_internal {

// ASCII lower case.
std::string ToLower(std::string s);
// The regular files of `dir` whose lower-cased extension is one of `extensions` (".png", ...),
// in natural order of their names ("2.png" < "10.png"). FileError when `dir` cannot be read.
std::vector<std::filesystem::path> ListFiles(const std::filesystem::path& dir,
                                             const std::vector<std::string>& extensions);
// FileError(dir or file, 0, what, "missing") unless it exists as a directory / regular file.
void RequireDirectory(const std::filesystem::path& dir, const std::string& what);
void RequireFile(const std::filesystem::path& file, const std::string& what);
// ReadTrajectory, with FileError for a positions-only file.
Trajectory ReadGtTrajectory(const std::filesystem::path& path, TrajectoryFormat format);
// Frame i gets the pose whose frame index is i. Returns how many frames got one.
size_t AttachByIndex(std::vector<DatasetFrame>& frames, const Trajectory& gt);
// The info line every loader logs: kind, root, frame count, frames with GT and the GT file.
void LogGt(const Dataset& d, size_t attached);

// The loaders of OpenDataset (dataset.h documents each layout): frames, intrinsics and ground
// truth; OpenDataset then checks the images.
Dataset OpenKitti(const std::filesystem::path& root, const DatasetOptions& options);
Dataset OpenTum(const std::filesystem::path& root, const DatasetOptions& options);
Dataset OpenEuroc(const std::filesystem::path& root, const DatasetOptions& options);
Dataset OpenImages(const std::filesystem::path& root, const DatasetOptions& options);

}  // namespace sparseloop::io_internal
