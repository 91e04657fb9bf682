#pragma once
// The caller's odometry covariances, one per keyframe step, as `sparseloop run
// --odometry-covariance FILE` reads them (docs/FORMATS.md, "Odometry covariance").
//
// One line per keyframe: "key c..." where key is the keyframe's timestamp (seconds) or, for
// datasets associated by index (KITTI, images:), its frame index, followed by the 6x6 covariance
// of the step from the previous keyframe to this one in tangent order [translation(3),
// rotation(3)] (raw units^2, rad^2; translation in the previous keyframe's frame, as
// KeyframeInput::odometry_covariance): either 21 numbers, the upper triangle row by row, or 36,
// the full matrix row-major (ROS order for a body-frame step). '#' comments and blank lines are
// skipped. Keys must increase strictly.
//
// Malformed input throws FileError naming the file, the 1-based line and what was expected: a
// column count other than 22 or 37, an unparsable or non-finite number, a non-symmetric 36-number
// matrix (1e-9 relative), a matrix that is not positive definite, a key not above the previous.
#include <filesystem>
#include <vector>

#include <Eigen/Core>

namespace sparseloop {

struct StepCovariance {
  double key = 0.0;  // timestamp (s) or frame index of the keyframe the step ends at
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();
};

std::vector<StepCovariance> ReadStepCovariances(const std::filesystem::path& path);

}  // namespace sparseloop
