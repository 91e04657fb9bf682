#pragma once
// Ground-truth loops from poses, and precision / recall of a loop detector.
//
// Definitions (also in docs/METRICS.md):
//  GT loops (DeriveGtLoops): for pose indices i > j of the gt trajectory, (query = frame_i,
//    match = frame_j) is a loop when |p_i - p_j| < distance, frame_i - frame_j >= min_gap and,
//    when max_view_angle_deg < 180, the angle between the two camera z axes (viewing directions,
//    R * e_z) is <= max_view_angle_deg.
//  A pair is always handled as (later, earlier): query = max, match = min of the two ids.
//  Detection d = (query, match, score) is CORRECT when some GT pair (d.query, m') exists with
//    |m' - d.match| <= frame_tolerance.
//  precision = correct detections / detections (nullopt when there are no detections).
//  GT queries = distinct query ids of the GT pairs. A GT query is RECALLED when at least one
//    correct detection has it as query. recall = recalled GT queries / GT queries (nullopt when
//    there are no GT pairs).
//  P/R curve: detections sorted by score, highest first; for every distinct score s (threshold:
//    keep detections with score >= s) one point with the precision and recall of the kept set.
//  recall_at_100p = the largest recall over curve points whose precision is exactly 1; 0 when
//    no such point exists (e.g. the top-scored detection is wrong); nullopt without GT pairs.
//
// Scoring by GT distance (ScoreLoopsByGtDistance, the rule of `run`'s loops.csv "correct" column
// and of scripts/benchmark): a detection is CORRECT when the GT positions of its two frames are
// closer than correct_distance, TRIVIAL when it is correct but the GT path between the two frames
// is shorter than trivial_path (the same stretch seen moments ago: neither a loop nor an error,
// left out of every count), FALSE otherwise, NO_GT when a frame has no GT pose. Precision, recall
// and the P/R curve are those above over the correct and false detections, a correct detection
// recalling its query when the query is a GT query. GT events: the GT queries grouped into runs
// whose consecutive queries are at most event_gap frames apart; an event is detected when an
// accepted correct detection has its query within event_margin frames of the run.
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "sparseloop/core/loop_pair.h"
#include "sparseloop/core/trajectory.h"

namespace sparseloop {

struct GtLoopOptions {
  double distance = 5.0;              // metres (gt units); pairs closer than this, > 0
  int64_t min_gap = 100;              // frames; minimum query - match frame difference, >= 1
  double max_view_angle_deg = 180.0;  // degrees in (0, 180]; 180 disables the check
  // gt units; minimum length of the GT path between the two frames (summed over the poses in
  // between, file order), >= 0; 0 disables. A revisit, not the same stretch of driving: two
  // frames 8 m apart on a straight street have 8 m of path between them, a revisit of the place
  // after a loop has the loop's length.
  double min_path = 0.0;
  void Check() const;
};

// Brute force over all pairs (O(n^2) distance checks). Result sorted by (query, match).
// Throws std::invalid_argument when max_view_angle_deg < 180 and gt.has_rotation is false.
std::vector<LoopPair> DeriveGtLoops(const Trajectory& gt, const GtLoopOptions& options = {});

struct Detection {
  int64_t query = 0;     // later frame id
  int64_t match = 0;     // earlier frame id it was matched to
  double score = 0.0;    // higher = more confident
  bool accepted = true;  // kept by the pose graph (loops.csv's "accepted" column)
};

// Reads the detector's loops.csv: a header line naming comma-separated columns, which must include
// "query", "match" and "score" (any order; "accepted" is read when present: 1 accepted, 0 or
// empty not (a loop into an earlier session); other columns ignored), then one detection per line.
// Blank lines are skipped. Throws FileError(path, line, expected, got) for a missing file, missing
// header columns, a wrong field count or an unparsable number.
std::vector<Detection> ReadDetections(const std::filesystem::path& path);

struct LoopEvalOptions {
  int64_t frame_tolerance = 0;  // frames; allowed |match - gt match| for a correct detection, >= 0
  void Check() const;
};

struct LoopPrPoint {
  double threshold = 0.0;  // score threshold (detections with score >= threshold kept)
  size_t detections = 0;   // kept detections
  size_t true_positives = 0;
  double precision = 0.0;
  double recall = 0.0;  // 0 when there are no GT queries
};

struct LoopPrResult {
  size_t num_detections = 0;
  size_t true_positives = 0;
  size_t false_positives = 0;
  size_t num_gt_pairs = 0;      // distinct GT pairs
  size_t num_gt_queries = 0;    // distinct GT query ids
  size_t recalled_queries = 0;  // GT queries with at least one correct detection
  std::optional<double> precision;
  std::optional<double> recall;
  std::optional<double> recall_at_100p;
  std::vector<bool> correct;       // per input detection, input order
  std::vector<LoopPrPoint> curve;  // by decreasing threshold
};

LoopPrResult EvaluateLoops(const std::vector<Detection>& detections,
                           const std::vector<LoopPair>& gt, const LoopEvalOptions& options = {});

// The GT pose of a frame id: by timestamp when `frame_times` has a pose with that frame id and
// the GT has timestamps (the GT pose nearest to it within max_dt), else the GT pose with that
// frame id. Without frame_times (nullptr): by frame id.
struct GtFrameLookup {
  const Trajectory* frame_times = nullptr;  // e.g. the raw poses matched to the frames
  double max_dt = 0.02;                     // seconds
};

// Per-loop verdict by GT distance alone: correct when the two frames' GT positions are closer
// than `threshold` (GT units); nullopt when a frame has no GT pose. threshold <= 0: 5 % of the
// GT path length, capped at 10 GT units (the default of `run --gt-loop-distance`).
struct LoopTruth {
  double threshold = 0.0;                    // GT units, the one used
  std::vector<std::optional<bool>> correct;  // per loop
  size_t num_correct() const;
  size_t num_false() const;
};
LoopTruth ClassifyLoopsByGtDistance(const std::vector<LoopPair>& loops, const Trajectory& gt,
                                    double threshold, const GtFrameLookup& lookup = {});

struct GtDistanceScoringOptions {
  double correct_distance = 10.0;  // GT units, > 0
  double trivial_path = 0.0;       // GT units, >= 0; 0: nothing is trivial
  int64_t event_gap = 10;          // frames, >= 1
  int64_t event_margin = 2;        // frames, >= 0
  GtFrameLookup lookup;
  void Check() const;
};

enum class LoopVerdict { kCorrect, kFalse, kTrivial, kNoGt };
const char* ToString(LoopVerdict verdict);  // "correct", "false", "trivial", "no_gt"

struct GtDistanceScore {
  std::vector<LoopVerdict> verdicts;  // per input detection, input order
  LoopPrResult all;       // over the correct and false detections (its `correct`: theirs, in order)
  LoopPrResult accepted;  // the same over the accepted ones
  size_t trivial = 0;
  size_t no_gt = 0;
  size_t events = 0;           // GT events (runs of GT queries)
  size_t events_detected = 0;  // with an accepted correct detection
};

// Search-area coverage: for each GT query frame that has a row in `areas` (frame ->
// the stored keyframe ids its search area held, after the detector's filters), whether one of its
// GT matches (a GT pair (query, m)) is among them: the loop the images could verify was at least
// compared. fraction = covered / queries (nullopt without queries); mean_candidates over them.
struct AreaCoverage {
  size_t queries = 0;
  size_t covered = 0;
  double mean_candidates = 0.0;
  std::optional<double> fraction;
};
AreaCoverage SearchAreaCoverage(const std::vector<LoopPair>& gt_loops,
                                const std::map<int64_t, std::vector<int64_t>>& areas);

// Keyframe id sets as text, the `area` column of frames.csv: ';'-separated ids and inclusive
// ranges "a-b" (ids ascending), e.g. "3;10-14;20". Empty set: "". FormatIdRanges sorts and drops
// duplicates; ParseIdRanges returns false on anything else than that syntax (ranges with b >= a).
std::string FormatIdRanges(std::vector<int64_t> ids);
bool ParseIdRanges(const std::string& text, std::vector<int64_t>* ids);

// Reads the frame and area columns of `run` / `detect`'s frames.csv (docs/FORMATS.md): frame ->
// ids. Throws FileError(path, line, expected, got) for a missing file or column, a wrong field
// count or an unparsable field.
std::map<int64_t, std::vector<int64_t>> ReadSearchAreas(const std::filesystem::path& path);

// `gt_loops` define the GT queries (DeriveGtLoops, or a pairs file); `gt` gives the positions and
// the path between frames (file order).
GtDistanceScore ScoreLoopsByGtDistance(const std::vector<Detection>& detections,
                                       const std::vector<LoopPair>& gt_loops, const Trajectory& gt,
                                       const GtDistanceScoringOptions& options);

}  // namespace sparseloop
