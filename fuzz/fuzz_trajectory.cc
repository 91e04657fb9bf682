// Fuzzes the trajectory readers: every format, plus auto-detection. Malformed input must raise
// FileError, never crash or hang. Two properties beyond that:
// - every pose a reader accepts is finite, with positions within +-kMaxCoordinate;
// - line endings and a byte order mark do not matter: the input with its line ends written as
//   "\n", as "\r\n", as a lone "\r", and with a UTF-8 BOM first, reads to the same poses (or the
//   same error line) in every format.
#include <cstdlib>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/limits.h"
#include "sparseloop/io/trajectory_io.h"

namespace {

using sparseloop::TrajectoryFormat;

// What a reader made of a file: the poses, or the line of its error (-1 - line).
std::vector<double> Outcome(const std::filesystem::path& path, TrajectoryFormat f) {
  std::vector<double> out;
  try {
    const sparseloop::Trajectory t = sparseloop::ReadTrajectory(path, f);
    for (const auto& p : t.poses) {
      const auto& x = p.world_from_cam.translation;
      if (!x.allFinite() || x.cwiseAbs().maxCoeff() > sparseloop::kMaxCoordinate) std::abort();
      out.insert(out.end(), {p.timestamp, static_cast<double>(p.frame), x.x(), x.y(), x.z()});
    }
  } catch (const sparseloop::FileError& e) {
    out = {-1.0 - e.line()};
  }
  return out;
}

// `text` with every line end ("\r\n", "\r" or "\n") written as `end`, without leading BOMs.
std::string WithLineEnds(const std::string& text, const std::string& end) {
  std::string out;
  size_t start = 0;
  while (text.compare(start, 3, "\xEF\xBB\xBF") == 0) start += 3;
  for (size_t i = start; i < text.size(); ++i) {
    if (text[i] == '\r' || text[i] == '\n') {
      out += end;
      if (text[i] == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
    } else {
      out += text[i];
    }
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const auto path = sparseloop::fuzz::WriteInput(data, size, "trajectory.txt");
  const auto write = [](const std::string& s, const std::string& name) {
    return sparseloop::fuzz::WriteInput(reinterpret_cast<const uint8_t*>(s.data()), s.size(), name);
  };
  const std::string lf = WithLineEnds(text, "\n");
  const auto lf_path = write(lf, "lf.txt");
  const auto crlf_path = write(WithLineEnds(text, "\r\n"), "crlf.txt");
  const auto cr_path = write(WithLineEnds(text, "\r"), "cr.txt");
  const auto bom_path = write("\xEF\xBB\xBF" + lf, "bom.txt");
  for (TrajectoryFormat f :
       {TrajectoryFormat::kAuto, TrajectoryFormat::kTum, TrajectoryFormat::kKitti,
        TrajectoryFormat::kEuroc, TrajectoryFormat::kPositions}) {
    Outcome(path, f);
    const std::vector<double> expected = Outcome(lf_path, f);
    for (const auto& other : {crlf_path, cr_path, bom_path}) {
      if (Outcome(other, f) != expected) std::abort();
    }
  }
  return 0;
}
