#include "sparseloop/io/dataset.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string_view>
#include <system_error>

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop {

namespace fs = std::filesystem;
using io_internal::ParseDouble;
using io_internal::ParseInt64;
using io_internal::Quote;
using io_internal::SplitComma;
using io_internal::SplitWhitespace;
using io_internal::TextFile;
using io_internal::TextLine;
using io_internal::Trim;

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

ImageSize ReadPngSize(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path.string(), 0, "an existing PNG image", "cannot open");
  std::array<unsigned char, 24> h{};
  in.read(reinterpret_cast<char*>(h.data()), h.size());
  static constexpr std::array<unsigned char, 8> kSignature = {0x89, 'P',  'N',  'G',
                                                              0x0D, 0x0A, 0x1A, 0x0A};
  if (in.gcount() != static_cast<std::streamsize>(h.size()) ||
      !std::equal(kSignature.begin(), kSignature.end(), h.begin()) || h[12] != 'I' ||
      h[13] != 'H' || h[14] != 'D' || h[15] != 'R') {
    throw FileError(path.string(), 0, "a PNG file (signature and IHDR chunk)", "other data");
  }
  auto be32 = [&h](size_t o) {
    return (static_cast<uint32_t>(h[o]) << 24) | (static_cast<uint32_t>(h[o + 1]) << 16) |
           (static_cast<uint32_t>(h[o + 2]) << 8) | static_cast<uint32_t>(h[o + 3]);
  };
  const uint32_t w = be32(16);
  const uint32_t hh = be32(20);
  if (w == 0 || hh == 0 || w > (1u << 30) || hh > (1u << 30)) {
    throw FileError(path.string(), 0, "a positive PNG image size", fmt::format("{}x{}", w, hh));
  }
  return {static_cast<int>(w), static_cast<int>(hh)};
}

namespace {

// JPEG: markers from SOI until the first start-of-frame (SOF0..SOF15 but DHT C4, JPG C8, DAC
// CC), whose segment holds precision, height, width.
std::optional<ImageSize> ReadJpegSize(std::istream& in) {
  for (;;) {
    if (in.get() != 0xFF) return std::nullopt;  // not at a marker: corrupt
    int marker = in.get();
    while (marker == 0xFF) marker = in.get();  // fill bytes
    if (marker == EOF) return std::nullopt;
    if (marker == 0x01 || marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7)) continue;
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // no frame header before the scan
    const int hi = in.get(), lo = in.get();
    if (lo == EOF || ((hi << 8) | lo) < 2) return std::nullopt;
    const int length = (hi << 8) | lo;
    const bool sof =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (!sof) {
      in.seekg(length - 2, std::ios::cur);
      continue;
    }
    std::array<unsigned char, 5> f{};
    if (!in.read(reinterpret_cast<char*>(f.data()), f.size())) return std::nullopt;
    const int height = (f[1] << 8) | f[2], width = (f[3] << 8) | f[4];
    if (width == 0 || height == 0) return std::nullopt;  // height 0: defined later (DNL)
    return ImageSize{width, height};
  }
}

// PGM/PPM/PBM ("P1".."P6"): width and height are the first two numbers after the magic, with
// '#' comments running to the end of their line.
std::optional<ImageSize> ReadPnmSize(std::istream& in) {
  int values[2] = {0, 0};
  for (int& v : values) {
    int c = in.get();
    while (c == '#' || std::isspace(c)) {
      if (c == '#') {
        while (c != '\n' && c != EOF) c = in.get();
      }
      c = in.get();
    }
    if (!std::isdigit(c)) return std::nullopt;
    for (; std::isdigit(c) && v < (1 << 24); c = in.get()) v = 10 * v + (c - '0');
  }
  if (values[0] <= 0 || values[1] <= 0) return std::nullopt;
  return ImageSize{values[0], values[1]};
}

// BMP: the DIB header after the 14-byte file header; BITMAPCOREHEADER (12 bytes, 16-bit sizes)
// or a larger one (32-bit signed sizes; a negative height is a top-down bitmap).
std::optional<ImageSize> ReadBmpSize(std::istream& in) {
  std::array<unsigned char, 24> h{};  // bytes 2..25 of the file
  if (!in.read(reinterpret_cast<char*>(h.data()), h.size())) return std::nullopt;
  auto le = [&h](size_t file_offset, int bytes) {
    uint32_t v = 0;
    for (int b = bytes - 1; b >= 0; --b) v = (v << 8) | h[file_offset - 2 + b];
    return v;
  };
  const uint32_t dib = le(14, 4);
  int64_t width = 0, height = 0;
  if (dib == 12) {
    width = le(18, 2), height = le(20, 2);
  } else if (dib >= 40) {
    width = static_cast<int32_t>(le(18, 4)), height = static_cast<int32_t>(le(22, 4));
  }
  height = std::abs(height);
  if (width <= 0 || height <= 0 || width > (1 << 30) || height > (1 << 30)) return std::nullopt;
  return ImageSize{static_cast<int>(width), static_cast<int>(height)};
}

// A JPEG's data ends with the EOI marker FF D9 (trailing NUL padding allowed); a truncated file
// does not.
bool JpegEndsWithEoi(const fs::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 4096);
  std::string bytes(static_cast<size_t>(std::max<std::streamoff>(tail, 0)), '\0');
  in.seekg(size - tail);
  if (!in || !in.read(bytes.data(), tail)) return false;
  while (!bytes.empty() && bytes.back() == '\0') bytes.pop_back();
  return bytes.size() >= 2 && static_cast<unsigned char>(bytes[bytes.size() - 2]) == 0xFF &&
         static_cast<unsigned char>(bytes.back()) == 0xD9;
}

bool IsJpeg(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return in.get() == 0xFF && in.get() == 0xD8;
}

}  // namespace

std::optional<ImageSize> ReadImageSize(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const int m0 = in.get(), m1 = in.get();
  if (m0 == 0x89 && m1 == 'P') {
    in.seekg(0);
    std::array<char, 24> h{};
    if (!in.read(h.data(), h.size()) || std::string_view(h.data() + 1, 3) != "PNG" ||
        std::string_view(h.data() + 12, 4) != "IHDR") {
      return std::nullopt;
    }
    return ReadPngSize(path);
  }
  if (m0 == 0xFF && m1 == 0xD8) return ReadJpegSize(in);
  if (m0 == 'P' && m1 >= '1' && m1 <= '6') return ReadPnmSize(in);
  if (m0 == 'B' && m1 == 'M') return ReadBmpSize(in);
  return std::nullopt;
}

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

size_t AttachGtByTime(std::vector<DatasetFrame>& frames, const Trajectory& gt, double max_dt) {
  size_t attached = 0;
  for (auto& f : frames) {
    if (const auto i = NearestPoseInTime(gt, f.timestamp, max_dt)) {
      f.gt_world_from_cam = gt.poses[*i].world_from_cam;
      ++attached;
    }
  }
  return attached;
}

namespace {

std::string ToLower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

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

std::vector<fs::path> ListFiles(const fs::path& dir, const std::vector<std::string>& extensions) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (!entry.is_regular_file()) continue;
    const std::string ext = ToLower(entry.path().extension().string());
    if (std::find(extensions.begin(), extensions.end(), ext) != extensions.end()) {
      files.push_back(entry.path());
    }
  }
  if (ec) throw FileError(dir.string(), 0, "a readable directory", ec.message());
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    return NaturalLess(a.filename().string(), b.filename().string());
  });
  return files;
}

void RequireDirectory(const fs::path& dir, const std::string& what) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw FileError(dir.string(), 0, what, "missing");
}

void RequireFile(const fs::path& file, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw FileError(file.string(), 0, what, "missing");
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

// ---------------------------------------------------------------------------------------- KITTI

CameraIntrinsics ReadKittiCalibP0(const fs::path& path) {
  const TextFile file(path);
  for (const auto& line : file.DataLines()) {
    const auto t = SplitWhitespace(line.text);
    if (t.empty() || t[0] != "P0:") continue;
    if (t.size() != 13) {
      throw FileError(file.name(), line.number, "'P0:' followed by 12 numbers",
                      fmt::format("{} numbers", t.size() - 1));
    }
    std::array<double, 12> p{};
    for (size_t i = 0; i < 12; ++i) {
      p[i] = ParseDouble(t[i + 1], file.name(), line.number, fmt::format("P0[{}]", i));
    }
    CameraIntrinsics k;
    k.fx = p[0];
    k.cx = p[2];
    k.fy = p[5];
    k.cy = p[6];
    if (!(k.fx > 0 && k.fy > 0)) {
      throw FileError(file.name(), line.number, "positive focal lengths in P0",
                      fmt::format("fx={} fy={}", k.fx, k.fy));
    }
    return k;
  }
  throw FileError(file.name(), 0, "a line 'P0: <12 numbers>'", "none");
}

std::vector<double> ReadKittiTimes(const fs::path& path) {
  const TextFile file(path);
  std::vector<double> times;
  for (const auto& line : file.DataLines()) {
    const auto t = SplitWhitespace(line.text);
    if (t.size() != 1) {
      throw FileError(file.name(), line.number, "1 column (time in seconds)",
                      fmt::format("{} columns", t.size()));
    }
    const double v = ParseDouble(t[0], file.name(), line.number, "time");
    if (!times.empty() && !(v > times.back())) {
      throw FileError(file.name(), line.number,
                      fmt::format("a time greater than the previous one ({})", times.back()),
                      fmt::format("{}", v));
    }
    times.push_back(v);
  }
  return times;
}

// The pose file of a KITTI folder; see docs/FORMATS.md "kitti:DIR" for the rule.
fs::path FindKittiPoses(const fs::path& dir, size_t frame_count) {
  const fs::path poses = dir / "poses.txt";
  std::error_code ec;
  if (fs::is_regular_file(poses, ec)) return poses;
  const fs::path seq = dir / (dir.filename().string() + ".txt");
  if (fs::is_regular_file(seq, ec)) return seq;
  for (const auto& candidate : ListFiles(dir, {".txt"})) {
    const std::string name = candidate.filename().string();
    if (name == "times.txt" || name == "calib.txt") continue;
    try {
      const TextFile file(candidate);
      const auto lines = file.DataLines();
      if (lines.size() == frame_count && SplitWhitespace(lines.front().text).size() == 12) {
        return candidate;
      }
    } catch (const FileError&) {
      continue;
    }
  }
  return {};
}

Dataset OpenKitti(const fs::path& root, const DatasetOptions& options) {
  Dataset d;
  d.kind = "kitti";
  d.root = root;
  const fs::path image_dir = root / "image_0";
  RequireDirectory(image_dir, "a KITTI image folder image_0/");
  const auto images = ListFiles(image_dir, {".png"});
  if (images.empty()) throw FileError(image_dir.string(), 0, "at least one .png image", "none");
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string stem = images[i].stem().string();
    if (!io_internal::LooksLikeInteger(stem) || std::stoll(stem) != static_cast<long long>(i)) {
      throw FileError(images[i].string(), 0,
                      fmt::format("images numbered consecutively from 000000 (number {})", i),
                      images[i].filename().string());
    }
  }
  const fs::path times_path = root / "times.txt";
  RequireFile(times_path, "a KITTI times.txt");
  const auto times = ReadKittiTimes(times_path);
  if (times.size() < images.size()) {
    throw FileError(times_path.string(), 0,
                    fmt::format("at least {} times (one per image)", images.size()),
                    fmt::format("{}", times.size()));
  }
  if (options.intrinsics) {
    d.intrinsics = *options.intrinsics;
    d.intrinsics_source = options.intrinsics_name;
  } else {
    const fs::path calib = root / "calib.txt";
    RequireFile(calib, fmt::format("a KITTI calib.txt (or {})", options.intrinsics_name));
    d.intrinsics = ReadKittiCalibP0(calib);
    d.intrinsics_source = calib.string();  // width and height: from the first image
  }
  for (size_t i = 0; i < images.size(); ++i) {
    d.frames.push_back(DatasetFrame{static_cast<int64_t>(i), times[i], images[i], std::nullopt});
  }
  d.gt_path = options.poses.empty() ? FindKittiPoses(root, images.size()) : options.poses;
  size_t attached = 0;
  if (!d.gt_path.empty()) {
    const Trajectory gt = ReadGtTrajectory(d.gt_path, TrajectoryFormat::kAuto);
    attached = AttachByIndex(d.frames, gt);
    if (attached != d.frames.size()) {
      const auto missing = std::find_if(d.frames.begin(), d.frames.end(), [](const auto& f) {
        return !f.gt_world_from_cam.has_value();
      });
      throw FileError(d.gt_path.string(), 0,
                      fmt::format("a pose for each of the {} images", d.frames.size()),
                      fmt::format("no pose for frame {}", missing->index));
    }
  }
  LogGt(d, attached);
  return d;
}

// ------------------------------------------------------------------------------------------ TUM

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

// ---------------------------------------------------------------------------------------- EuRoC

struct YamlValue {
  std::string text;  // scalar, or "[...]" for a list
  int line = 0;
};

std::map<std::string, YamlValue> ParseYamlSubset(const TextFile& file) {
  std::map<std::string, YamlValue> out;
  std::string parent;
  std::string open_key;  // key of a list still missing its ']'
  for (const auto& line : file.lines()) {
    std::string_view text = line.text;
    if (const size_t hash = text.find('#'); hash != std::string_view::npos) {
      text = text.substr(0, hash);
    }
    if (Trim(text).empty()) continue;
    if (!open_key.empty()) {
      if (text.find(':') != std::string_view::npos) {  // a new key: the list was never closed
        throw FileError(file.name(), out[open_key].line,
                        fmt::format("a closing ']' for {}", open_key),
                        fmt::format("a new key on line {}", line.number));
      }
      out[open_key].text += " " + std::string(Trim(text));
      if (text.find(']') != std::string_view::npos) open_key.clear();
      continue;
    }
    const std::string_view trimmed = Trim(text);
    if (trimmed.front() == '%' || trimmed.substr(0, 3) == "---") continue;
    const size_t colon = trimmed.find(':');
    if (colon == std::string_view::npos) {
      throw FileError(file.name(), line.number, "'key: value'", Quote(trimmed));
    }
    const std::string key(Trim(trimmed.substr(0, colon)));
    const std::string value(Trim(trimmed.substr(colon + 1)));
    const bool indented = text.front() == ' ' || text.front() == '\t';
    std::string full_key = key;
    if (indented && !parent.empty()) {
      full_key = parent + "." + key;
    } else {
      parent = key;
    }
    out[full_key] = YamlValue{value, line.number};
    if (!value.empty() && value.front() == '[' && value.find(']') == std::string::npos) {
      open_key = full_key;
    }
  }
  if (!open_key.empty()) {
    throw FileError(file.name(), out[open_key].line, fmt::format("a closing ']' for {}", open_key),
                    "end of file");
  }
  return out;
}

std::vector<double> YamlNumbers(const std::map<std::string, YamlValue>& yaml,
                                const std::string& key, const std::string& file) {
  const auto it = yaml.find(key);
  if (it == yaml.end()) throw FileError(file, 0, fmt::format("a '{}:' entry", key), "none");
  std::string_view text = Trim(it->second.text);
  if (text.size() < 2 || text.front() != '[' || text.back() != ']') {
    throw FileError(file, it->second.line, fmt::format("a list [a, b, ...] for {}", key),
                    Quote(text));
  }
  text = Trim(text.substr(1, text.size() - 2));
  std::vector<double> out;
  if (text.empty()) return out;
  for (auto token : SplitComma(text)) {
    out.push_back(ParseDouble(token, file, it->second.line, key));
  }
  return out;
}

}  // namespace

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
  if (auto it = yaml.find("distortion_model"); it != yaml.end()) model = it->second.text;
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

namespace {

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
    if (fs::is_regular_file(yaml, ec)) body_from_cam = ReadEurocSensorYaml(yaml).body_from_cam;
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

// --------------------------------------------------------------------------------------- images

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
