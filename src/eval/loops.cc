#include "sparseloop/eval/loops.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/text_lines.h"

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

// The fields of one CSV line, each trimmed; a field in double quotes (RFC 4180, as loops.csv
// writes an image name holding a comma) may hold commas, its doubled quotes read as one.
std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t b = line.find_first_not_of(" \t\r", start);
    if (b != std::string::npos && line[b] == '"') {
      std::string field;
      size_t i = b + 1;
      for (; i < line.size(); ++i) {
        if (line[i] != '"') {
          field += line[i];
        } else if (i + 1 < line.size() && line[i + 1] == '"') {
          field += '"';
          ++i;
        } else {
          break;  // the closing quote
        }
      }
      const size_t comma = line.find(',', i);
      out.push_back(field);
      if (comma == std::string::npos) break;
      start = comma + 1;
      continue;
    }
    const size_t comma = line.find(',', start);
    std::string field =
        line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const auto fb = field.find_first_not_of(" \t\r");
    const auto fe = field.find_last_not_of(" \t\r");
    out.push_back(fb == std::string::npos ? std::string() : field.substr(fb, fe - fb + 1));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

// True when `record` ends inside a quoted field: an odd number of quotes (a doubled quote inside a
// field counts two). Such a record goes on on the next line (RFC 4180: a quoted field may hold a
// line end, as loops.csv writes an image name holding one).
bool EndsInsideQuotes(const std::string& record) {
  return std::count(record.begin(), record.end(), '"') % 2 == 1;
}

bool ParseInt(const std::string& s, int64_t& value) {
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc() && ptr == s.data() + s.size() && !s.empty();
}

size_t ColumnOf(const std::vector<std::string>& header, const std::string& name,
                const std::filesystem::path& path, int header_line, const std::string& expected,
                const std::string& line) {
  const auto it = std::find(header.begin(), header.end(), name);
  if (it == header.end()) throw FileError(path.string(), header_line, expected, "'" + line + "'");
  return static_cast<size_t>(it - header.begin());
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

// A CSV file with a header line (blank lines skipped): `columns(header, header_line, text)`
// once, then `row(fields, line_no)` per row, each with the header's field count (FileError
// otherwise). `kind` names the file in the error for a missing file.
void ReadCsv(
    const std::filesystem::path& path, const std::string& kind,
    const std::function<void(const std::vector<std::string>&, int, const std::string&)>& columns,
    const std::function<void(const std::vector<std::string>&, int)>& row) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path.string(), 0, "a readable " + kind + " CSV file", "cannot open");
  // The whole text, split as every reader splits lines (a BOM, "\r\n" and lone "\r" ends).
  const std::string text(std::istreambuf_iterator<char>(in), {});
  const std::vector<std::string_view> lines = SplitLines(text);
  size_t next = 0;
  int line_no = 0;
  std::string line;
  std::vector<std::string> header;
  while (header.empty() && next < lines.size()) {
    line = std::string(lines[next++]);
    ++line_no;
    if (line.find_first_not_of(" \t") != std::string::npos) header = SplitCsv(line);
  }
  if (header.empty()) throw FileError(path.string(), 0, "a CSV header line", "an empty file");
  columns(header, line_no, line);
  while (next < lines.size()) {
    line = std::string(lines[next++]);
    ++line_no;
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    const int record_line = line_no;
    while (EndsInsideQuotes(line) && next < lines.size()) {
      line += '\n';
      line += lines[next++];
      ++line_no;
    }
    const auto fields = SplitCsv(line);
    if (fields.size() != header.size()) {
      throw FileError(path.string(), record_line,
                      fmt::format("{} comma-separated fields", header.size()),
                      fmt::format("{}", fields.size()));
    }
    row(fields, record_line);
  }
}

}  // namespace

std::vector<Detection> ReadDetections(const std::filesystem::path& path) {
  size_t query_col = 0, match_col = 0, score_col = 0, accepted_col = 0;
  bool has_accepted = false;
  std::vector<Detection> out;
  const auto columns = [&](const std::vector<std::string>& header, int header_line,
                           const std::string& text) {
    const auto column = [&](const std::string& name) {
      return ColumnOf(header, name, path, header_line,
                      "a header with columns query, match and score", text);
    };
    query_col = column("query");
    match_col = column("match");
    score_col = column("score");
    const auto accepted_it = std::find(header.begin(), header.end(), "accepted");
    has_accepted = accepted_it != header.end();
    accepted_col = static_cast<size_t>(accepted_it - header.begin());
  };
  const auto row = [&](const std::vector<std::string>& fields, int line_no) {
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
    if (has_accepted) {
      const std::string& a = fields[accepted_col];
      if (a != "0" && a != "1" && !a.empty()) {
        throw FileError(path.string(), line_no, "0, 1 or nothing in the accepted column",
                        "'" + a + "'");
      }
      d.accepted = a == "1";
    }
    out.push_back(d);
  };
  ReadCsv(path, "loops", columns, row);
  return out;
}

void LoopEvalOptions::Check() const {
  SL_CHECK_MSG(frame_tolerance >= 0, "frame_tolerance must be >= 0 frames, got {}",
               frame_tolerance);
}

namespace {

using GtMatches = std::map<int64_t, std::set<int64_t>>;  // GT query -> its GT matches

GtMatches GtMatchesOf(const std::vector<LoopPair>& gt) {
  GtMatches gt_matches;  // as (later, earlier)
  for (const auto& p : gt) {
    gt_matches[std::max(p.query, p.match)].insert(std::min(p.query, p.match));
  }
  return gt_matches;
}

// Precision, recall and the P/R curve of `detections` given each one's verdict: thresholds swept
// from the highest score down; a correct detection recalls its query when it is a GT query.
LoopPrResult SweepThresholds(const std::vector<Detection>& detections,
                             const std::vector<bool>& correct, const GtMatches& gt_matches) {
  LoopPrResult result;
  result.num_detections = detections.size();
  result.num_gt_queries = gt_matches.size();
  for (const auto& [q, ms] : gt_matches) result.num_gt_pairs += ms.size();
  result.correct = correct;
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
      if (!correct[k]) continue;
      ++tp;
      const int64_t query = std::max(detections[k].query, detections[k].match);
      if (gt_matches.count(query)) recalled.insert(query);
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

void CheckScores(const std::vector<Detection>& detections) {
  for (size_t k = 0; k < detections.size(); ++k) {
    SL_CHECK_MSG(std::isfinite(detections[k].score), "detection {} has a non-finite score", k);
  }
}

}  // namespace

LoopPrResult EvaluateLoops(const std::vector<Detection>& detections,
                           const std::vector<LoopPair>& gt, const LoopEvalOptions& options) {
  options.Check();
  CheckScores(detections);
  const GtMatches gt_matches = GtMatchesOf(gt);
  std::vector<bool> correct(detections.size(), false);
  for (size_t k = 0; k < detections.size(); ++k) {
    const int64_t query = std::max(detections[k].query, detections[k].match);
    const int64_t match = std::min(detections[k].query, detections[k].match);
    const auto it = gt_matches.find(query);
    if (it == gt_matches.end()) continue;
    // Any GT match within [match - tol, match + tol]?
    const auto lo = it->second.lower_bound(match - options.frame_tolerance);
    correct[k] = lo != it->second.end() && *lo <= match + options.frame_tolerance;
  }
  return SweepThresholds(detections, correct, gt_matches);
}

// ---- Scoring by GT distance ----

size_t LoopTruth::num_correct() const {
  return std::count(correct.begin(), correct.end(), std::optional<bool>(true));
}

size_t LoopTruth::num_false() const {
  return std::count(correct.begin(), correct.end(), std::optional<bool>(false));
}

namespace {

// Index into gt.poses of each frame id's GT pose (GtFrameLookup's rule).
class GtIndexOfFrame {
 public:
  GtIndexOfFrame(const Trajectory& gt, const GtFrameLookup& lookup) : gt_(gt), lookup_(lookup) {
    for (size_t i = 0; i < gt.poses.size(); ++i) by_frame_[gt.poses[i].frame] = i;
    if (lookup.frame_times != nullptr) {
      for (const auto& p : lookup.frame_times->poses) time_of_frame_[p.frame] = p.timestamp;
    }
  }
  std::optional<size_t> operator()(int64_t frame) const {
    const auto t = time_of_frame_.find(frame);
    if (gt_.has_timestamps && t != time_of_frame_.end()) {
      return NearestPoseInTime(gt_, t->second, lookup_.max_dt);
    }
    const auto it = by_frame_.find(frame);
    if (it == by_frame_.end()) return std::nullopt;
    return it->second;
  }

 private:
  const Trajectory& gt_;
  GtFrameLookup lookup_;
  std::unordered_map<int64_t, size_t> by_frame_;
  std::unordered_map<int64_t, double> time_of_frame_;
};

double DefaultLoopTruthThreshold(const Trajectory& gt) {
  const auto dist = gt.CumulativeDistances();
  return dist.empty() ? 1.0 : std::min(0.05 * dist.back(), 10.0);
}

}  // namespace

LoopTruth ClassifyLoopsByGtDistance(const std::vector<LoopPair>& loops, const Trajectory& gt,
                                    double threshold, const GtFrameLookup& lookup) {
  LoopTruth truth;
  truth.threshold = threshold > 0 ? threshold : DefaultLoopTruthThreshold(gt);
  const GtIndexOfFrame index_of(gt, lookup);
  for (const LoopPair& l : loops) {
    const auto q = index_of(l.query);
    const auto m = index_of(l.match);
    if (q && m) {
      const double d =
          (gt.poses[*q].world_from_cam.translation - gt.poses[*m].world_from_cam.translation)
              .norm();
      truth.correct.push_back(d < truth.threshold);
    } else {
      truth.correct.push_back(std::nullopt);
    }
  }
  return truth;
}

void GtDistanceScoringOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(correct_distance) && correct_distance > 0.0,
               "correct_distance must be > 0, got {}", correct_distance);
  SL_CHECK_MSG(std::isfinite(trivial_path) && trivial_path >= 0.0,
               "trivial_path must be >= 0, got {}", trivial_path);
  SL_CHECK_MSG(event_gap >= 1, "event_gap must be >= 1 frame, got {}", event_gap);
  SL_CHECK_MSG(event_margin >= 0, "event_margin must be >= 0 frames, got {}", event_margin);
  SL_CHECK_MSG(std::isfinite(lookup.max_dt) && lookup.max_dt >= 0.0,
               "max_dt must be >= 0 s, got {}", lookup.max_dt);
}

const char* ToString(LoopVerdict verdict) {
  switch (verdict) {
    case LoopVerdict::kCorrect:
      return "correct";
    case LoopVerdict::kFalse:
      return "false";
    case LoopVerdict::kTrivial:
      return "trivial";
    case LoopVerdict::kNoGt:
      return "no_gt";
  }
  return "?";
}

namespace {

// Runs of GT queries whose consecutive members are at most `gap` frames apart: [first, last].
std::vector<std::pair<int64_t, int64_t>> GtEvents(const GtMatches& gt_matches, int64_t gap) {
  std::vector<std::pair<int64_t, int64_t>> events;
  for (const auto& [q, ms] : gt_matches) {  // ascending query
    if (!events.empty() && q - events.back().second <= gap) {
      events.back().second = q;
    } else {
      events.emplace_back(q, q);
    }
  }
  return events;
}

}  // namespace

GtDistanceScore ScoreLoopsByGtDistance(const std::vector<Detection>& detections,
                                       const std::vector<LoopPair>& gt_loops, const Trajectory& gt,
                                       const GtDistanceScoringOptions& options) {
  options.Check();
  CheckScores(detections);
  const GtIndexOfFrame index_of(gt, options.lookup);
  const std::vector<double> path = gt.CumulativeDistances();
  GtDistanceScore score;
  std::vector<Detection> kept, kept_accepted;
  std::vector<bool> correct, correct_accepted;
  for (const Detection& d : detections) {
    const auto q = index_of(d.query);
    const auto m = index_of(d.match);
    LoopVerdict verdict = LoopVerdict::kNoGt;
    if (q && m) {
      const double dist =
          (gt.poses[*q].world_from_cam.translation - gt.poses[*m].world_from_cam.translation)
              .norm();
      const bool near = dist < options.correct_distance;
      verdict = !near                                                  ? LoopVerdict::kFalse
                : std::abs(path[*q] - path[*m]) < options.trivial_path ? LoopVerdict::kTrivial
                                                                       : LoopVerdict::kCorrect;
    }
    score.verdicts.push_back(verdict);
    if (verdict == LoopVerdict::kTrivial) ++score.trivial;
    if (verdict == LoopVerdict::kNoGt) ++score.no_gt;
    if (verdict != LoopVerdict::kCorrect && verdict != LoopVerdict::kFalse) continue;
    kept.push_back(d);
    correct.push_back(verdict == LoopVerdict::kCorrect);
    if (!d.accepted) continue;
    kept_accepted.push_back(d);
    correct_accepted.push_back(verdict == LoopVerdict::kCorrect);
  }
  const GtMatches gt_matches = GtMatchesOf(gt_loops);
  score.all = SweepThresholds(kept, correct, gt_matches);
  score.accepted = SweepThresholds(kept_accepted, correct_accepted, gt_matches);
  const auto events = GtEvents(gt_matches, options.event_gap);
  score.events = events.size();
  for (const auto& [first, last] : events) {
    for (size_t k = 0; k < kept_accepted.size(); ++k) {
      const int64_t query = std::max(kept_accepted[k].query, kept_accepted[k].match);
      if (correct_accepted[k] && query >= first - options.event_margin &&
          query <= last + options.event_margin) {
        ++score.events_detected;
        break;
      }
    }
  }
  return score;
}

AreaCoverage SearchAreaCoverage(const std::vector<LoopPair>& gt_loops,
                                const std::map<int64_t, std::vector<int64_t>>& areas) {
  std::map<int64_t, std::vector<int64_t>> matches;  // GT query -> its GT matches
  for (const LoopPair& p : gt_loops)
    matches[std::max(p.query, p.match)].push_back(std::min(p.query, p.match));
  AreaCoverage c;
  double candidates = 0.0;
  for (const auto& [query, truth] : matches) {
    const auto it = areas.find(query);
    if (it == areas.end()) continue;
    const std::vector<int64_t>& area = it->second;  // ascending (FormatIdRanges / ParseIdRanges)
    ++c.queries;
    candidates += static_cast<double>(area.size());
    for (const int64_t m : truth) {
      if (std::binary_search(area.begin(), area.end(), m)) {
        ++c.covered;
        break;
      }
    }
  }
  if (c.queries > 0) {
    c.fraction = static_cast<double>(c.covered) / static_cast<double>(c.queries);
    c.mean_candidates = candidates / static_cast<double>(c.queries);
  }
  return c;
}

std::string FormatIdRanges(std::vector<int64_t> ids) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  std::string out;
  for (size_t i = 0; i < ids.size();) {
    size_t j = i;
    while (j + 1 < ids.size() && ids[j + 1] == ids[j] + 1) ++j;
    if (!out.empty()) out += ';';
    out += j == i ? fmt::format("{}", ids[i]) : fmt::format("{}-{}", ids[i], ids[j]);
    i = j + 1;
  }
  return out;
}

bool ParseIdRanges(const std::string& text, std::vector<int64_t>* ids) {
  ids->clear();
  if (text.empty()) return true;
  size_t start = 0;
  while (true) {
    const size_t semi = text.find(';', start);
    const std::string item =
        text.substr(start, semi == std::string::npos ? std::string::npos : semi - start);
    const size_t dash = item.find('-', 1);  // not a leading sign
    int64_t a = 0;
    int64_t b = 0;
    if (dash == std::string::npos) {
      if (!ParseInt(item, a)) return false;
      b = a;
    } else if (!ParseInt(item.substr(0, dash), a) || !ParseInt(item.substr(dash + 1), b) || b < a) {
      return false;
    }
    if (a < 0 || (!ids->empty() && a <= ids->back())) return false;  // ascending, no duplicates
    for (int64_t v = a; v <= b; ++v) ids->push_back(v);
    if (semi == std::string::npos) return true;
    start = semi + 1;
  }
}

std::map<int64_t, std::vector<int64_t>> ReadSearchAreas(const std::filesystem::path& path) {
  size_t frame_col = 0, area_col = 0;
  std::map<int64_t, std::vector<int64_t>> out;
  const auto columns = [&](const std::vector<std::string>& header, int header_line,
                           const std::string& text) {
    const std::string expected =
        "a header with columns frame and area (frames.csv of run / detect)";
    frame_col = ColumnOf(header, "frame", path, header_line, expected, text);
    area_col = ColumnOf(header, "area", path, header_line, expected, text);
  };
  const auto row = [&](const std::vector<std::string>& fields, int line_no) {
    int64_t frame = 0;
    if (!ParseInt(fields[frame_col], frame) || frame < 0) {
      throw FileError(path.string(), line_no, "a non-negative integer frame id",
                      "'" + fields[frame_col] + "'");
    }
    std::vector<int64_t> ids;
    if (!ParseIdRanges(fields[area_col], &ids)) {
      throw FileError(path.string(), line_no,
                      "keyframe ids and ranges a-b, ';'-separated, ascending",
                      "'" + fields[area_col] + "'");
    }
    out[frame] = std::move(ids);
  };
  ReadCsv(path, "frames", columns, row);
  return out;
}

}  // namespace sparseloop
