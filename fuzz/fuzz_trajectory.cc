// Fuzzes the trajectory readers: every format, plus auto-detection. Malformed input must raise
// FileError, never crash or hang.
#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using sparseloop::TrajectoryFormat;
  const auto path = sparseloop::fuzz::WriteInput(data, size, "trajectory.txt");
  for (TrajectoryFormat f :
       {TrajectoryFormat::kAuto, TrajectoryFormat::kTum, TrajectoryFormat::kKitti,
        TrajectoryFormat::kEuroc, TrajectoryFormat::kPositions}) {
    try {
      sparseloop::ReadTrajectory(path, f);
    } catch (const sparseloop::Error&) {
    }
  }
  return 0;
}
