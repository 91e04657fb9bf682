#include "sparseloop/io/trajectory_io.h"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <vector>

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/limits.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/quaternion.h"
#include "sparseloop/io/atomic_file.h"

namespace sparseloop {

using io_internal::LooksLikeInteger;
using io_internal::LooksLikeNumber;
using io_internal::ParseDouble;
using io_internal::ParseInt64;
using io_internal::Quote;
using io_internal::SplitComma;
using io_internal::SplitWhitespace;
using io_internal::TextFile;
using io_internal::TextLine;

TrajectoryFormat ParseTrajectoryFormat(const std::string& name) {
  if (name == "auto") return TrajectoryFormat::kAuto;
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  if (name == "euroc") return TrajectoryFormat::kEuroc;
  if (name == "positions") return TrajectoryFormat::kPositions;
  SL_CHECK_MSG(false, "unknown trajectory format '{}' (valid: auto, tum, kitti, euroc, positions)",
               name);
  return TrajectoryFormat::kAuto;  // unreachable
}

std::string ToString(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kAuto:
      return "auto";
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kKitti:
      return "kitti";
    case TrajectoryFormat::kEuroc:
      return "euroc";
    case TrajectoryFormat::kPositions:
      return "positions";
  }
  return "unknown";
}

namespace {

// Deviation of a 3x3 block from a rotation: max |R^T R - I|, and +inf when det(R) <= 0.
double RotationDeviation(const Eigen::Matrix3d& r) {
  if (!(r.determinant() > 0.0)) return std::numeric_limits<double>::infinity();
  return (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

// Numbers of a whitespace line, or nullopt when a token is not a number (detection only).
std::optional<std::vector<double>> NumbersOrNull(const std::vector<std::string_view>& tokens) {
  std::vector<double> out;
  for (auto t : tokens) {
    if (!LooksLikeNumber(t)) return std::nullopt;
    out.push_back(std::strtod(std::string(t).c_str(), nullptr));
  }
  return out;
}

bool IsUnitQuaternion(double x, double y, double z, double w) {
  const double n = std::sqrt(x * x + y * y + z * z + w * w);
  return std::isfinite(n) && std::abs(n - 1.0) <= kQuaternionNormTolerance;
}

bool IsRotationRowMajor(const std::vector<double>& v, size_t offset) {
  Matrix3x4d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[offset + 4 * r + c];
  if (!m.allFinite()) return false;
  return RotationDeviation(m.leftCols<3>()) <= kRotationTolerance;
}

TrajectoryFormat DetectFromLine(const TextLine& line, const std::string& file) {
  if (line.text.find(',') != std::string_view::npos) return TrajectoryFormat::kEuroc;
  const auto tokens = SplitWhitespace(line.text);
  const size_t n = tokens.size();
  const auto numbers = NumbersOrNull(tokens);
  const bool first_is_int = n > 0 && LooksLikeInteger(tokens[0]);
  if (numbers) {
    const auto& v = *numbers;
    if (n == 8 && IsUnitQuaternion(v[4], v[5], v[6], v[7])) return TrajectoryFormat::kTum;
    if (n == 12 && IsRotationRowMajor(v, 0)) return TrajectoryFormat::kKitti;
    if (n == 13 && first_is_int && IsRotationRowMajor(v, 1)) return TrajectoryFormat::kKitti;
  }
  if (n >= 4 && first_is_int) return TrajectoryFormat::kPositions;
  if (n == 8) return TrajectoryFormat::kTum;
  if (n == 12 || n == 13) return TrajectoryFormat::kKitti;
  throw FileError(file, line.number,
                  "a trajectory line: TUM (8 columns), KITTI (12 or 13), EuRoC CSV (commas) or "
                  "positions (integer frame + >= 3 columns)",
                  fmt::format("{} columns", n));
}

std::vector<TextLine> NonEmptyDataLines(const TextFile& file) {
  auto lines = file.DataLines();
  if (lines.empty()) throw FileError(file.name(), 0, "at least one data line", "none");
  return lines;
}

Eigen::Quaterniond CheckedQuaternion(const Eigen::Quaterniond& q, const std::string& file,
                                     int line) {
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    throw FileError(file, line,
                    fmt::format("a unit quaternion (| |q| - 1 | <= {})", kQuaternionNormTolerance),
                    fmt::format("|q| = {:.6g}", norm));
  }
  return q.normalized();
}

Rigid3d CheckedPose(const Matrix3x4d& m, const std::string& file, int line) {
  const double dev = RotationDeviation(m.leftCols<3>());
  if (!(dev <= kRotationTolerance)) {
    throw FileError(
        file, line,
        fmt::format("a rotation in the 3x3 block (max |R^T R - I| <= {}, det > 0)",
                    kRotationTolerance),
        std::isfinite(dev) ? fmt::format("max |R^T R - I| = {:.6g}", dev) : "det(R) <= 0");
  }
  try {
    return Rigid3d::FromMatrix3x4(m, kRotationTolerance);
  } catch (const std::invalid_argument& e) {
    throw FileError(file, line, "a rotation in the 3x3 block", e.what());
  }
}

// A position coordinate: a finite number within +-kMaxCoordinate.
double ParseCoordinate(std::string_view token, const std::string& file, int line,
                       std::string_view what) {
  const double v = ParseDouble(token, file, line, what);
  if (std::abs(v) > kMaxCoordinate) {
    throw FileError(file, line,
                    fmt::format("a coordinate within +-{:g} for {} (larger ones overflow the "
                                "computations on positions)",
                                kMaxCoordinate, what),
                    Quote(token));
  }
  return v;
}

void CheckColumnCount(size_t got, size_t expected, const std::string& file, int line,
                      const char* layout) {
  if (got != expected) {
    throw FileError(file, line, fmt::format("{} columns ({})", expected, layout),
                    fmt::format("{} columns", got));
  }
}

// The "got" of a non-increasing timestamp / frame index; a repeated one names the option that
// reads such files (e.g. the TUM fr2/desk ground truth).
std::string NotIncreasing(const std::string& value, bool repeated) {
  if (!repeated) return value;
  return value +
         " (a repeat: to keep the first pose of each, convert the file with `sparseloop convert "
         "--drop-duplicates` or set TrajectoryReadOptions::drop_duplicate_timestamps)";
}

void WarnDropped(const TextFile& file, size_t dropped) {
  if (dropped > 0) {
    Logger().warn("{}: dropped {} pose(s) repeating the previous timestamp / frame index",
                  file.name(), dropped);
  }
}

Trajectory ReadTum(const TextFile& file, const TrajectoryReadOptions& options) {
  size_t dropped = 0;
  Trajectory traj;
  traj.has_rotation = true;
  traj.has_timestamps = true;
  const auto& name = file.name();
  int64_t frame = 0;
  for (const auto& line : NonEmptyDataLines(file)) {
    const auto t = SplitWhitespace(line.text);
    CheckColumnCount(t.size(), 8, name, line.number, "TUM: t x y z qx qy qz qw");
    StampedPose pose;
    pose.timestamp = ParseDouble(t[0], name, line.number, "timestamp");
    const Eigen::Vector3d p(ParseCoordinate(t[1], name, line.number, "x"),
                            ParseCoordinate(t[2], name, line.number, "y"),
                            ParseCoordinate(t[3], name, line.number, "z"));
    const auto q = QuaternionFromXyzw(
        ParseDouble(t[4], name, line.number, "qx"), ParseDouble(t[5], name, line.number, "qy"),
        ParseDouble(t[6], name, line.number, "qz"), ParseDouble(t[7], name, line.number, "qw"));
    if (!traj.poses.empty() && options.drop_duplicate_timestamps &&
        pose.timestamp == traj.poses.back().timestamp) {
      ++dropped;
      continue;
    }
    if (!traj.poses.empty() && !(pose.timestamp > traj.poses.back().timestamp)) {
      throw FileError(name, line.number,
                      fmt::format("a timestamp greater than the previous one ({:.9f})",
                                  traj.poses.back().timestamp),
                      NotIncreasing(fmt::format("{:.9f}", pose.timestamp),
                                    pose.timestamp == traj.poses.back().timestamp));
    }
    pose.world_from_cam = Rigid3d(CheckedQuaternion(q, name, line.number), p);
    pose.frame = frame++;
    traj.poses.push_back(pose);
  }
  WarnDropped(file, dropped);
  return traj;
}

Trajectory ReadKitti(const TextFile& file, const TrajectoryReadOptions& options) {
  size_t dropped = 0;
  Trajectory traj;
  traj.has_rotation = true;
  traj.has_timestamps = false;
  const auto& name = file.name();
  const auto lines = NonEmptyDataLines(file);
  const size_t columns = SplitWhitespace(lines.front().text).size();
  if (columns != 12 && columns != 13) {
    throw FileError(name, lines.front().number,
                    "12 columns (KITTI 3x4 row-major) or 13 (frame index + 12)",
                    fmt::format("{} columns", columns));
  }
  const bool indexed = columns == 13;
  int64_t row = 0;
  for (const auto& line : lines) {
    const auto t = SplitWhitespace(line.text);
    CheckColumnCount(t.size(), columns, name, line.number,
                     indexed ? "KITTI: frame + 12 numbers of the 3x4 [R|t]"
                             : "KITTI: 12 numbers of the 3x4 [R|t]");
    StampedPose pose;
    pose.frame = indexed ? ParseInt64(t[0], name, line.number, "frame index") : row;
    const size_t off = indexed ? 1 : 0;
    Matrix3x4d m;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        const std::string what = fmt::format("matrix entry ({},{})", r, c);
        m(r, c) = c == 3 ? ParseCoordinate(t[off + 4 * r + c], name, line.number, what)
                         : ParseDouble(t[off + 4 * r + c], name, line.number, what);
      }
    }
    if (!traj.poses.empty() && options.drop_duplicate_timestamps &&
        pose.frame == traj.poses.back().frame) {
      ++dropped;
      continue;
    }
    if (!traj.poses.empty() && !(pose.frame > traj.poses.back().frame)) {
      throw FileError(
          name, line.number,
          fmt::format("a frame index greater than the previous one ({})", traj.poses.back().frame),
          NotIncreasing(fmt::format("{}", pose.frame), pose.frame == traj.poses.back().frame));
    }
    pose.world_from_cam = CheckedPose(m, name, line.number);
    pose.timestamp = static_cast<double>(pose.frame);
    traj.poses.push_back(pose);
    ++row;
  }
  WarnDropped(file, dropped);
  return traj;
}

Trajectory ReadEuroc(const TextFile& file, const TrajectoryReadOptions& options) {
  size_t dropped = 0;
  Trajectory traj;
  traj.has_rotation = true;
  traj.has_timestamps = true;
  const auto& name = file.name();
  const auto lines = NonEmptyDataLines(file);
  const size_t columns = SplitComma(lines.front().text).size();
  if (columns < 8) {
    throw FileError(name, lines.front().number,
                    ">= 8 comma-separated columns (EuRoC: t[ns],px,py,pz,qw,qx,qy,qz,...)",
                    fmt::format("{} columns", columns));
  }
  int64_t frame = 0;
  int64_t previous_ns = 0;
  for (const auto& line : lines) {
    const auto t = SplitComma(line.text);
    CheckColumnCount(t.size(), columns, name, line.number,
                     "EuRoC CSV, same count as the first data line");
    const int64_t ns = ParseInt64(t[0], name, line.number, "timestamp [ns]");
    const Eigen::Vector3d p(ParseCoordinate(t[1], name, line.number, "p_x"),
                            ParseCoordinate(t[2], name, line.number, "p_y"),
                            ParseCoordinate(t[3], name, line.number, "p_z"));
    const auto q = QuaternionFromWxyz(
        ParseDouble(t[4], name, line.number, "q_w"), ParseDouble(t[5], name, line.number, "q_x"),
        ParseDouble(t[6], name, line.number, "q_y"), ParseDouble(t[7], name, line.number, "q_z"));
    for (size_t i = 8; i < t.size(); ++i) {
      ParseDouble(t[i], name, line.number, fmt::format("column {}", i + 1));
    }
    if (!traj.poses.empty() && options.drop_duplicate_timestamps && ns == previous_ns) {
      ++dropped;
      continue;
    }
    if (!traj.poses.empty() && ns <= previous_ns) {
      throw FileError(name, line.number,
                      fmt::format("a timestamp greater than the previous one ({} ns)", previous_ns),
                      NotIncreasing(fmt::format("{} ns", ns), ns == previous_ns));
    }
    previous_ns = ns;
    StampedPose pose;
    pose.timestamp =
        static_cast<double>(ns / 1000000000) + static_cast<double>(ns % 1000000000) * 1e-9;
    pose.frame = frame++;
    pose.world_from_cam = Rigid3d(CheckedQuaternion(q, name, line.number), p);
    traj.poses.push_back(pose);
  }
  WarnDropped(file, dropped);
  return traj;
}

Trajectory ReadPositions(const TextFile& file, const TrajectoryReadOptions& options) {
  size_t dropped = 0;
  Trajectory traj;
  traj.has_rotation = false;
  traj.has_timestamps = false;
  const auto& name = file.name();
  const auto lines = NonEmptyDataLines(file);
  const size_t columns = SplitWhitespace(lines.front().text).size();
  if (columns < 4) {
    throw FileError(name, lines.front().number, ">= 4 columns (positions: frame x y z ...)",
                    fmt::format("{} columns", columns));
  }
  for (const auto& line : lines) {
    const auto t = SplitWhitespace(line.text);
    CheckColumnCount(t.size(), columns, name, line.number,
                     "positions: frame x y z ..., same count as the first data line");
    StampedPose pose;
    pose.frame = ParseInt64(t[0], name, line.number, "frame index");
    pose.world_from_cam.translation =
        Eigen::Vector3d(ParseCoordinate(t[1], name, line.number, "x"),
                        ParseCoordinate(t[2], name, line.number, "y"),
                        ParseCoordinate(t[3], name, line.number, "z"));
    for (size_t i = 4; i < t.size(); ++i) {
      ParseDouble(t[i], name, line.number, fmt::format("column {}", i + 1));
    }
    if (!traj.poses.empty() && options.drop_duplicate_timestamps &&
        pose.frame == traj.poses.back().frame) {
      ++dropped;
      continue;
    }
    if (!traj.poses.empty() && !(pose.frame > traj.poses.back().frame)) {
      throw FileError(
          name, line.number,
          fmt::format("a frame index greater than the previous one ({})", traj.poses.back().frame),
          NotIncreasing(fmt::format("{}", pose.frame), pose.frame == traj.poses.back().frame));
    }
    pose.timestamp = static_cast<double>(pose.frame);
    traj.poses.push_back(pose);
  }
  WarnDropped(file, dropped);
  return traj;
}

TrajectoryFormat DetectFormat(const TextFile& file) {
  const auto lines = NonEmptyDataLines(file);
  return DetectFromLine(lines.front(), file.name());
}

}  // namespace

TrajectoryFormat DetectTrajectoryFormat(const std::filesystem::path& path) {
  return DetectFormat(TextFile(path));
}

Trajectory ReadTrajectory(const std::filesystem::path& path, TrajectoryFormat format) {
  return ReadTrajectory(path, format, TrajectoryReadOptions{});
}

Trajectory ReadTrajectory(const std::filesystem::path& path, TrajectoryFormat format,
                          const TrajectoryReadOptions& options) {
  return ReadTrajectoryFile(path, format, options).trajectory;
}

TrajectoryFile ReadTrajectoryFile(const std::filesystem::path& path, TrajectoryFormat format,
                                  const TrajectoryReadOptions& options) {
  options.Check();
  const TextFile file(path);
  if (format == TrajectoryFormat::kAuto) {
    format = DetectFormat(file);
    Logger().debug("{}: detected trajectory format {}", file.name(), ToString(format));
  }
  if (options.require_rotation && format == TrajectoryFormat::kPositions) {
    throw FileError(file.name(), NonEmptyDataLines(file).front().number,
                    "a trajectory with orientations (TUM, KITTI or EuRoC)",
                    "a positions-only line (frame x y z ...)");
  }
  switch (format) {
    case TrajectoryFormat::kTum:
      return {ReadTum(file, options), format};
    case TrajectoryFormat::kKitti:
      return {ReadKitti(file, options), format};
    case TrajectoryFormat::kEuroc:
      return {ReadEuroc(file, options), format};
    case TrajectoryFormat::kPositions:
      return {ReadPositions(file, options), format};
    case TrajectoryFormat::kAuto:
      break;
  }
  SL_CHECK_MSG(false, "unreachable trajectory format");
  return {};
}

std::string FormatSeconds(double seconds) {
  const std::string fixed = fmt::format("{:.9f}", seconds);
  double back = 0.0;
  const auto [ptr, ec] = std::from_chars(fixed.data(), fixed.data() + fixed.size(), back);
  if (ec == std::errc() && ptr == fixed.data() + fixed.size() && back == seconds) return fixed;
  return fmt::format("{}", seconds);  // fmt's shortest round-trip form
}

namespace {

// The integer nanoseconds of EuRoC CSV for each pose's time (nearest), or std::invalid_argument
// naming `path` and the frame for a time beyond int64 or less than 1 ns from the previous,
// different, one: written, they would be a wrapped value or a repeat the reader refuses.
std::vector<int64_t> EurocNanoseconds(const std::filesystem::path& path, const Trajectory& traj) {
  std::vector<int64_t> out;
  out.reserve(traj.poses.size());
  for (size_t i = 0; i < traj.poses.size(); ++i) {
    const StampedPose& p = traj.poses[i];
    // Whole seconds and the fraction apart: t * 1e9 as one double rounds to 256 ns at 1e9 s.
    const double whole = std::floor(p.timestamp);
    const auto fraction = static_cast<int64_t>(std::llround((p.timestamp - whole) * 1e9));
    int64_t ns = 0;
    const bool fits =
        std::abs(whole) < 1e10 &&
        !__builtin_mul_overflow(static_cast<int64_t>(whole), int64_t{1000000000}, &ns) &&
        !__builtin_add_overflow(ns, fraction, &ns);
    if (!fits) {
      throw std::invalid_argument(
          fmt::format("{}: expected times EuRoC CSV can hold (integer nanoseconds in int64, within "
                      "+-9223372036.854775807 s), got frame {} at {} s",
                      path.string(), p.frame, p.timestamp));
    }
    if (i > 0 && ns == out.back() && p.timestamp != traj.poses[i - 1].timestamp) {
      const StampedPose& before = traj.poses[i - 1];
      throw std::invalid_argument(fmt::format(
          "{}: expected times EuRoC CSV can hold (integer nanoseconds: at least 1 ns apart), got "
          "frame {} at {} s, {:.3g} ns from frame {} at {} s: both would be written as {} ns",
          path.string(), p.frame, FormatSeconds(p.timestamp),
          1e9 * std::abs(p.timestamp - before.timestamp), before.frame,
          FormatSeconds(before.timestamp), ns));
    }
    out.push_back(ns);
  }
  return out;
}

}  // namespace

void WriteTrajectory(const std::filesystem::path& path, const Trajectory& traj,
                     TrajectoryFormat format) {
  SL_CHECK_MSG(format != TrajectoryFormat::kAuto,
               "WriteTrajectory needs an explicit format (tum, kitti, euroc, positions)");
  SL_CHECK_MSG(traj.has_rotation || format == TrajectoryFormat::kPositions,
               "a positions-only trajectory can only be written as 'positions', not '{}'",
               ToString(format));
  for (const auto& p : traj.poses) {
    SL_CHECK_MSG(std::isfinite(p.timestamp) && p.world_from_cam.translation.allFinite() &&
                     p.world_from_cam.rotation.coeffs().allFinite(),
                 "trajectory pose of frame {} is not finite", p.frame);
  }
  const std::vector<int64_t> euroc_ns =
      format == TrajectoryFormat::kEuroc ? EurocNanoseconds(path, traj) : std::vector<int64_t>{};
  if (format == TrajectoryFormat::kKitti) {
    for (size_t i = 0; i < traj.poses.size(); ++i) {
      if (traj.poses[i].frame != static_cast<int64_t>(i)) {
        Logger().warn("{}: KITTI output has no frame column; frame {} is written on row {}",
                      path.string(), traj.poses[i].frame, i);
        break;
      }
    }
  }
  WriteFileAtomically(path, [&](std::ostream& out) {
    fmt::memory_buffer buf;
    if (format == TrajectoryFormat::kTum) {
      fmt::format_to(std::back_inserter(buf), "# timestamp tx ty tz qx qy qz qw\n");
    } else if (format == TrajectoryFormat::kEuroc) {
      fmt::format_to(std::back_inserter(buf),
                     "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x "
                     "[],q_RS_y [],q_RS_z []\n");
    }
    for (size_t row = 0; row < traj.poses.size(); ++row) {
      const StampedPose& p = traj.poses[row];
      const Eigen::Vector3d& t = p.world_from_cam.translation;
      switch (format) {
        case TrajectoryFormat::kTum: {
          const auto q = QuaternionToXyzw(p.world_from_cam.rotation);
          fmt::format_to(std::back_inserter(buf), "{} {} {} {} {} {} {} {}\n",
                         FormatSeconds(p.timestamp), t.x(), t.y(), t.z(), q[0], q[1], q[2], q[3]);
          break;
        }
        case TrajectoryFormat::kKitti: {
          const Matrix3x4d m = p.world_from_cam.ToMatrix3x4();
          fmt::format_to(std::back_inserter(buf), "{} {} {} {} {} {} {} {} {} {} {} {}\n", m(0, 0),
                         m(0, 1), m(0, 2), m(0, 3), m(1, 0), m(1, 1), m(1, 2), m(1, 3), m(2, 0),
                         m(2, 1), m(2, 2), m(2, 3));
          break;
        }
        case TrajectoryFormat::kEuroc: {
          const auto q = QuaternionToWxyz(p.world_from_cam.rotation);
          fmt::format_to(std::back_inserter(buf), "{},{},{},{},{},{},{},{}\n", euroc_ns[row], t.x(),
                         t.y(), t.z(), q[0], q[1], q[2], q[3]);
          break;
        }
        case TrajectoryFormat::kPositions:
          fmt::format_to(std::back_inserter(buf), "{} {} {} {}\n", p.frame, t.x(), t.y(), t.z());
          break;
        case TrajectoryFormat::kAuto:
          break;
      }
      if (buf.size() > (1 << 16)) {
        out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
        buf.clear();
      }
    }
    out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  });
}

}  // namespace sparseloop
