#include "sparseloop/eval/loops.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

void GtLoopOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(distance) && distance > 0.0, "GT loop distance must be > 0, got {}",
               distance);
  SL_CHECK_MSG(min_gap >= 1, "GT loop min_gap must be >= 1 frame, got {}", min_gap);
  SL_CHECK_MSG(max_view_angle_deg > 0.0 && max_view_angle_deg <= 180.0,
               "GT loop max_view_angle_deg must be in (0, 180], got {}", max_view_angle_deg);
  SL_CHECK_MSG(std::isfinite(min_path) && min_path >= 0.0, "GT loop min_path must be >= 0, got {}",
               min_path);
}

std::vector<LoopPair> DeriveGtLoops(const Trajectory& gt, const GtLoopOptions& options) {
  options.Check();
  const bool check_angle = options.max_view_angle_deg < 180.0;
  SL_CHECK_MSG(!check_angle || gt.has_rotation,
               "a view-angle limit needs a ground truth with orientations");
  const double min_cos = std::cos(options.max_view_angle_deg * std::numbers::pi / 180.0);
  const size_t n = gt.size();
  std::vector<Eigen::Vector3d> pos(n);
  std::vector<Eigen::Vector3d> view(n);
  for (size_t i = 0; i < n; ++i) {
    pos[i] = gt.poses[i].world_from_cam.translation;
    view[i] = gt.poses[i].world_from_cam.rotation * Eigen::Vector3d::UnitZ();
  }
  const std::vector<double> path = gt.CumulativeDistances();  // GT path length from the first pose
  const double dist_sq = options.distance * options.distance;
  std::vector<LoopPair> out;
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) {
      const int64_t query = gt.poses[i].frame;
      const int64_t match = gt.poses[j].frame;
      if (query - match < options.min_gap) continue;
      if ((pos[i] - pos[j]).squaredNorm() >= dist_sq) continue;
      if (std::abs(path[i] - path[j]) < options.min_path) continue;
      // cos(angle) >= cos(max) <=> angle <= max; clamp for rounding.
      if (check_angle && std::clamp(view[i].dot(view[j]), -1.0, 1.0) < min_cos) continue;
      out.push_back({query, match});
    }
  }
  std::sort(out.begin(), out.end(), [](const LoopPair& a, const LoopPair& b) {
    return a.query != b.query ? a.query < b.query : a.match < b.match;
  });
  return out;
}

namespace {

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string field =
        line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const auto b = field.find_first_not_of(" \t\r");
    const auto e = field.find_last_not_of(" \t\r");
    out.push_back(b == std::string::npos ? std::string() : field.substr(b, e - b + 1));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

bool ParseInt(const std::string& s, int64_t& value) {
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc() && ptr == s.data() + s.size() && !s.empty();
}

bool ParseDouble(const std::string& s, double& value) {
  if (s.empty()) return false;
  try {
    size_t used = 0;
    value = std::stod(s, &used);
    return used == s.size() && std::isfinite(value);
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

std::vector<Detection> ReadDetections(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw FileError(path.string(), 0, "a readable loops CSV file", "cannot open");
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    header = SplitCsv(line);
    break;
  }
  if (header.empty()) throw FileError(path.string(), 0, "a CSV header line", "an empty file");
  const int header_line = line_no;
  auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) {
      throw FileError(path.string(), header_line, "a header with columns query, match and score",
                      "'" + line + "'");
    }
    return static_cast<size_t>(it - header.begin());
  };
  const size_t query_col = column("query");
  const size_t match_col = column("match");
  const size_t score_col = column("score");
  std::vector<Detection> out;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto fields = SplitCsv(line);
    if (fields.size() != header.size()) {
      throw FileError(path.string(), line_no,
                      fmt::format("{} comma-separated fields", header.size()),
                      fmt::format("{}", fields.size()));
    }
    Detection d;
    if (!ParseInt(fields[query_col], d.query) || d.query < 0) {
      throw FileError(path.string(), line_no, "a non-negative integer query frame id",
                      "'" + fields[query_col] + "'");
    }
    if (!ParseInt(fields[match_col], d.match) || d.match < 0) {
      throw FileError(path.string(), line_no, "a non-negative integer match frame id",
                      "'" + fields[match_col] + "'");
    }
    if (!ParseDouble(fields[score_col], d.score)) {
      throw FileError(path.string(), line_no, "a finite number as score",
                      "'" + fields[score_col] + "'");
    }
    out.push_back(d);
  }
  return out;
}

void LoopEvalOptions::Check() const {
  SL_CHECK_MSG(frame_tolerance >= 0, "frame_tolerance must be >= 0 frames, got {}",
               frame_tolerance);
}

LoopPrResult EvaluateLoops(const std::vector<Detection>& detections,
                           const std::vector<LoopPair>& gt, const LoopEvalOptions& options) {
  options.Check();
  // GT matches per query, as (later, earlier).
  std::map<int64_t, std::set<int64_t>> gt_matches;
  for (const auto& p : gt) {
    gt_matches[std::max(p.query, p.match)].insert(std::min(p.query, p.match));
  }
  LoopPrResult result;
  result.num_detections = detections.size();
  result.num_gt_queries = gt_matches.size();
  for (const auto& [q, ms] : gt_matches) result.num_gt_pairs += ms.size();

  result.correct.resize(detections.size(), false);
  for (size_t k = 0; k < detections.size(); ++k) {
    SL_CHECK_MSG(std::isfinite(detections[k].score), "detection {} has a non-finite score", k);
    const int64_t query = std::max(detections[k].query, detections[k].match);
    const int64_t match = std::min(detections[k].query, detections[k].match);
    const auto it = gt_matches.find(query);
    if (it == gt_matches.end()) continue;
    // Any GT match within [match - tol, match + tol]?
    const auto lo = it->second.lower_bound(match - options.frame_tolerance);
    result.correct[k] = lo != it->second.end() && *lo <= match + options.frame_tolerance;
  }

  // Sweep thresholds from the highest score down.
  std::vector<size_t> order(detections.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return detections[a].score > detections[b].score; });
  std::unordered_set<int64_t> recalled;
  size_t tp = 0;
  std::optional<double> best_recall_at_100p;
  for (size_t pos = 0; pos < order.size();) {
    const double threshold = detections[order[pos]].score;
    for (; pos < order.size() && detections[order[pos]].score == threshold; ++pos) {
      const size_t k = order[pos];
      if (!result.correct[k]) continue;
      ++tp;
      recalled.insert(std::max(detections[k].query, detections[k].match));
    }
    LoopPrPoint point;
    point.threshold = threshold;
    point.detections = pos;
    point.true_positives = tp;
    point.precision = static_cast<double>(tp) / static_cast<double>(pos);
    point.recall = result.num_gt_queries == 0 ? 0.0
                                              : static_cast<double>(recalled.size()) /
                                                    static_cast<double>(result.num_gt_queries);
    if (tp == pos) best_recall_at_100p = std::max(best_recall_at_100p.value_or(0.0), point.recall);
    result.curve.push_back(point);
  }
  result.true_positives = tp;
  result.false_positives = detections.size() - tp;
  result.recalled_queries = recalled.size();
  if (!detections.empty()) {
    result.precision = static_cast<double>(tp) / static_cast<double>(detections.size());
  }
  if (result.num_gt_queries > 0) {
    result.recall =
        static_cast<double>(recalled.size()) / static_cast<double>(result.num_gt_queries);
    result.recall_at_100p = best_recall_at_100p.value_or(0.0);
  }
  return result;
}

}  // namespace sparseloop
