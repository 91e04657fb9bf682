#pragma once
// Strict readers and writers for the trajectory formats of the vSLAM ecosystem. See
// docs/FORMATS.md for the exact layouts, the auto-detection rule and the error messages.
//
//  kTum        "t x y z qx qy qz qw" (seconds), '#' comments, blank lines allowed.
//  kKitti      12 numbers per line, row-major 3x4 world_from_cam [R|t]; or 13 with a leading
//              integer frame index (frames need not start at 0).
//  kEuroc      EuRoC ASL CSV "timestamp[ns],px,py,pz,qw,qx,qy,qz[,extra columns...]".
//  kPositions  "frame x y z [more columns...]": only the first 4 columns are read, the
//              orientation is identity and Trajectory::has_rotation is false.
//
// Every malformed input throws sparseloop::FileError naming the file, the 1-based line and what
// was expected (missing/empty file, wrong column count, unparsable or non-finite number, non-unit
// quaternion, non-rotation 3x3 block, timestamps or frame indices not strictly increasing).
#include <filesystem>
#include <string>

#include "sparseloop/core/trajectory.h"

namespace sparseloop {

enum class TrajectoryFormat { kAuto, kTum, kKitti, kEuroc, kPositions };

// "auto", "tum", "kitti", "euroc", "positions" (case-sensitive); anything else throws
// std::invalid_argument listing the valid names.
TrajectoryFormat ParseTrajectoryFormat(const std::string& name);
std::string ToString(TrajectoryFormat format);

// Tolerances of the strict readers (also documented in docs/FORMATS.md).
inline constexpr double kQuaternionNormTolerance = 1e-3;  // | |q| - 1 | above this -> FileError
inline constexpr double kRotationTolerance = 1e-3;        // max |R^T R - I| above this -> FileError

// The format of an existing file according to the auto-detection rule (first data line only).
// Throws FileError for a missing/empty file or when no rule matches.
TrajectoryFormat DetectTrajectoryFormat(const std::filesystem::path& path);

struct TrajectoryReadOptions {
  // Strict by default: equal timestamps (or frame indices) are a FileError. True: keep the first
  // pose of each run of equal timestamps / frame indices and log a warning. Real files need this:
  // the official TUM fr2/desk groundtruth.txt repeats 1311868229.5760 (line 10863).
  bool drop_duplicate_timestamps = false;
  // True: a positions-only file (kPositions, given or detected) is a FileError at its first data
  // line, for callers that need each pose's rotation (a renderer's camera, a pose graph).
  bool require_rotation = false;

  void Check() const {}
};

// Reads a trajectory; `format` kAuto applies DetectTrajectoryFormat, any other value is obeyed.
// Quaternions within kQuaternionNormTolerance of unit norm and 3x3 blocks within
// kRotationTolerance of a rotation are normalised / re-orthonormalised. The file is read once
// (detection included), so a FIFO or /dev/stdin works as a path.
Trajectory ReadTrajectory(const std::filesystem::path& path,
                          TrajectoryFormat format = TrajectoryFormat::kAuto);
Trajectory ReadTrajectory(const std::filesystem::path& path, TrajectoryFormat format,
                          const TrajectoryReadOptions& options);

// A trajectory and the format it was read as (kAuto resolved by the detection rule).
struct TrajectoryFile {
  Trajectory trajectory;
  TrajectoryFormat format = TrajectoryFormat::kAuto;
};
// ReadTrajectory that also says which format it read: detect and read in one pass over the file,
// where DetectTrajectoryFormat then ReadTrajectory would read a pipe twice.
TrajectoryFile ReadTrajectoryFile(const std::filesystem::path& path, TrajectoryFormat format,
                                  const TrajectoryReadOptions& options = {});

// Writes atomically (WriteFileAtomically). kTum: the time as FormatSeconds writes it, poses with
// shortest round-trip precision; kKitti: 12 numbers per line (the frame index is not written);
// kEuroc: CSV with integer nanosecond timestamps; kPositions: "frame x y z". kAuto throws
// std::invalid_argument; so does writing a positions-only trajectory (has_rotation false) as TUM,
// KITTI or EuRoC, and writing as EuRoC a time beyond the int64 nanoseconds it holds (+-9.2e9 s)
// or two different times less than 1 ns apart (the file would repeat a time its reader refuses).
// Nothing is written when it throws.
void WriteTrajectory(const std::filesystem::path& path, const Trajectory& traj,
                     TrajectoryFormat format);

// A time in seconds as text that reads back as the same double: 9 decimals ("0.500000000") when
// they do, else the shortest text that does ("1e-12", "0.5000000001"). Distinct times stay
// distinct through a file (TUM trajectories, a render's times.txt).
std::string FormatSeconds(double seconds);

}  // namespace sparseloop
