#include "sparseloop/eval/loops.h"

#include <algorithm>
#include <fstream>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "sparseloop/core/error.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// GT pairs. (20, 150) is written in the "wrong" order and is handled as (150, 20).
// GT queries: {100, 101, 150, 200, 300} -> 5; pairs: 6.
const std::vector<LoopPair> kGt = {{100, 10}, {100, 11}, {101, 11},
                                   {20, 150}, {200, 50}, {300, 60}};

// Detections (query, match, score), worked by hand below.
const std::vector<Detection> kDetections = {
    {100, 12, 0.9},  // d0: GT matches of 100 are {10, 11}: correct iff tolerance >= 1
    {250, 5, 0.95},  // d1: 250 has no GT partner: false positive with the highest score
    {101, 11, 0.8},  // d2: exact
    {200, 53, 0.7},  // d3: GT match 50: correct iff tolerance >= 3
    {100, 10, 0.6},  // d4: exact; second detection for query 100
    {300, 60, 0.5},  // d5: exact
    {400, 1, 0.5},   // d6: false positive, ties with d5
};

TEST(EvaluateLoops, HandWorkedToleranceOne) {
  LoopEvalOptions options;
  options.frame_tolerance = 1;
  const auto r = EvaluateLoops(kDetections, kGt, options);
  // correct: d0, d2, d4, d5 -> TP 4, FP 3, precision 4/7.
  EXPECT_EQ(r.correct, (std::vector<bool>{true, false, true, false, true, true, false}));
  EXPECT_EQ(r.num_detections, 7u);
  EXPECT_EQ(r.true_positives, 4u);
  EXPECT_EQ(r.false_positives, 3u);
  EXPECT_EQ(r.num_gt_pairs, 6u);
  EXPECT_EQ(r.num_gt_queries, 5u);
  ASSERT_TRUE(r.precision && r.recall && r.recall_at_100p);
  EXPECT_DOUBLE_EQ(*r.precision, 4.0 / 7.0);
  // recalled queries: 100, 101, 300 -> 3/5.
  EXPECT_EQ(r.recalled_queries, 3u);
  EXPECT_DOUBLE_EQ(*r.recall, 0.6);
  // The top-scored detection (d1) is wrong, so precision is never 1: recall@100%P = 0.
  EXPECT_DOUBLE_EQ(*r.recall_at_100p, 0.0);
  // Curve by decreasing threshold (kept, TP, P, R):
  //  0.95: d1          1, 0, 0,   0
  //  0.9 : + d0        2, 1, 1/2, 1/5
  //  0.8 : + d2        3, 2, 2/3, 2/5
  //  0.7 : + d3        4, 2, 1/2, 2/5
  //  0.6 : + d4        5, 3, 3/5, 2/5   (query 100 already recalled)
  //  0.5 : + d5, d6    7, 4, 4/7, 3/5   (ties enter together)
  ASSERT_EQ(r.curve.size(), 6u);
  const double thresholds[] = {0.95, 0.9, 0.8, 0.7, 0.6, 0.5};
  const size_t kept[] = {1, 2, 3, 4, 5, 7};
  const size_t tp[] = {0, 1, 2, 2, 3, 4};
  const double recall[] = {0, 0.2, 0.4, 0.4, 0.4, 0.6};
  for (size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(r.curve[k].threshold, thresholds[k]);
    EXPECT_EQ(r.curve[k].detections, kept[k]);
    EXPECT_EQ(r.curve[k].true_positives, tp[k]);
    EXPECT_DOUBLE_EQ(r.curve[k].precision, double(tp[k]) / double(kept[k]));
    EXPECT_DOUBLE_EQ(r.curve[k].recall, recall[k]);
  }
}

TEST(EvaluateLoops, RecallAtFullPrecisionWithoutTheHighFalsePositive) {
  std::vector<Detection> detections = kDetections;
  detections.erase(detections.begin() + 1);  // drop d1
  LoopEvalOptions options;
  options.frame_tolerance = 1;
  const auto r = EvaluateLoops(detections, kGt, options);
  // Thresholds 0.9 (P 1, R 1/5) and 0.8 (P 1, R 2/5) are perfect; 0.7 adds the wrong d3.
  EXPECT_DOUBLE_EQ(*r.recall_at_100p, 0.4);
  EXPECT_DOUBLE_EQ(*r.precision, 4.0 / 6.0);
}

TEST(EvaluateLoops, FrameToleranceChangesTheAnswer) {
  LoopEvalOptions exact;
  const auto r0 = EvaluateLoops(kDetections, kGt, exact);
  // tolerance 0: d0 and d3 wrong -> TP d2, d4, d5; recalled 101, 100, 300.
  EXPECT_EQ(r0.true_positives, 3u);
  EXPECT_DOUBLE_EQ(*r0.precision, 3.0 / 7.0);
  EXPECT_DOUBLE_EQ(*r0.recall, 0.6);
  LoopEvalOptions wide;
  wide.frame_tolerance = 3;
  const auto r3 = EvaluateLoops(kDetections, kGt, wide);
  // tolerance 3: d3 becomes correct too -> TP 5; recalled adds 200 -> 4/5.
  EXPECT_EQ(r3.true_positives, 5u);
  EXPECT_DOUBLE_EQ(*r3.recall, 0.8);
}

TEST(EvaluateLoops, PairOrderAndEmptyInputs) {
  // A detection written (earlier, later) is the same pair; the swapped GT pair (20, 150) counts.
  const auto r = EvaluateLoops({{11, 101, 1.0}, {150, 20, 0.5}}, kGt);
  EXPECT_EQ(r.true_positives, 2u);
  EXPECT_DOUBLE_EQ(*r.recall, 0.4);
  EXPECT_DOUBLE_EQ(*r.recall_at_100p, 0.4);

  const auto none = EvaluateLoops({}, kGt);
  EXPECT_FALSE(none.precision);
  EXPECT_DOUBLE_EQ(*none.recall, 0.0);
  EXPECT_DOUBLE_EQ(*none.recall_at_100p, 0.0);
  EXPECT_TRUE(none.curve.empty());

  const auto no_gt = EvaluateLoops(kDetections, {});
  EXPECT_FALSE(no_gt.recall);
  EXPECT_FALSE(no_gt.recall_at_100p);
  EXPECT_DOUBLE_EQ(*no_gt.precision, 0.0);

  LoopEvalOptions bad;
  bad.frame_tolerance = -1;
  EXPECT_THROW(EvaluateLoops(kDetections, kGt, bad), std::invalid_argument);
}

Trajectory HandMadeTrajectory() {
  // Frames 0..5 along x every 10 m; frame 6 returns near frame 0, frame 7 near frame 2.
  const double xs[] = {0, 10, 20, 30, 40, 50, 0.5, 20.2};
  Trajectory t;
  for (int i = 0; i < 8; ++i) {
    StampedPose p;
    p.frame = i;
    p.timestamp = i;
    p.world_from_cam.translation = Eigen::Vector3d(xs[i], 0, 0);
    t.poses.push_back(p);
  }
  return t;
}

TEST(DeriveGtLoops, HandMadeKnownAnswers) {
  auto t = HandMadeTrajectory();
  GtLoopOptions options;
  options.distance = 1.0;
  options.min_gap = 3;
  EXPECT_EQ(DeriveGtLoops(t, options), (std::vector<LoopPair>{{6, 0}, {7, 2}}));
  options.min_gap = 6;  // 7 - 2 = 5 is too close in time
  EXPECT_EQ(DeriveGtLoops(t, options), (std::vector<LoopPair>{{6, 0}}));
  options.min_gap = 3;
  options.distance = 0.4;  // 0.5 m apart is not < 0.4
  EXPECT_EQ(DeriveGtLoops(t, options), (std::vector<LoopPair>{{7, 2}}));

  // Frame 6 looks backwards (180 deg about y): excluded by a 90 deg view limit.
  t.poses[6].world_from_cam.rotation =
      Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitY());
  options.distance = 1.0;
  options.max_view_angle_deg = 90.0;
  EXPECT_EQ(DeriveGtLoops(t, options), (std::vector<LoopPair>{{7, 2}}));
  // A 30 deg yaw difference passes 45 but not 20.
  t.poses[6].world_from_cam.rotation =
      Eigen::AngleAxisd(30.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY());
  options.max_view_angle_deg = 45.0;
  EXPECT_EQ(DeriveGtLoops(t, options).size(), 2u);
  options.max_view_angle_deg = 20.0;
  EXPECT_EQ(DeriveGtLoops(t, options).size(), 1u);

  t.has_rotation = false;
  EXPECT_THROW(DeriveGtLoops(t, options), std::invalid_argument);
  options.max_view_angle_deg = 180.0;
  EXPECT_EQ(DeriveGtLoops(t, options).size(), 2u);
}

// Driving down a straight street, frames 3 m apart are within 4 m and 3 frames apart: not a
// revisit. min_path keeps only pairs with enough GT path between them.
TEST(DeriveGtLoops, MinPathExcludesTheSameStretchOfDriving) {
  Trajectory t;
  for (int i = 0; i <= 11; ++i) {
    StampedPose p;
    p.frame = i;
    p.timestamp = i;
    // Frames 0..10 along x every 1 m, frame 11 back at (5, 0.5): path 10 + |(-5, 0.5)|.
    p.world_from_cam.translation = i <= 10 ? Eigen::Vector3d(i, 0, 0) : Eigen::Vector3d(5, 0.5, 0);
    t.poses.push_back(p);
  }
  GtLoopOptions options;
  options.distance = 4.0;
  options.min_gap = 3;
  const auto all = DeriveGtLoops(t, options);
  EXPECT_EQ(std::count_if(all.begin(), all.end(), [](const LoopPair& p) { return p.query <= 10; }),
            8);             // (3,0) .. (10,7): the same stretch of street
  options.min_path = 12.0;  // frame 11 has 15.02 - k metres of path back to frame k
  EXPECT_EQ(DeriveGtLoops(t, options), (std::vector<LoopPair>{{11, 2}, {11, 3}}));
  options.min_path = -1.0;
  EXPECT_THROW(DeriveGtLoops(t, options), std::invalid_argument);
}

TEST(ReadDetections, ParsesColumnsByHeaderName) {
  const auto dir = test::TempDir();
  const auto path = dir / "loops.csv";
  {
    std::ofstream out(path);
    out << "inliers,score,match,query,extra\n"
        << "30,0.75,12,140,x\n"
        << "\n"
        << "5, 0.25 ,3,99,y\n";
  }
  const auto d = ReadDetections(path);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].query, 140);
  EXPECT_EQ(d[0].match, 12);
  EXPECT_EQ(d[0].score, 0.75);
  EXPECT_EQ(d[1].query, 99);
  EXPECT_EQ(d[1].score, 0.25);
  EXPECT_TRUE(d[0].accepted);  // no accepted column: every detection counts as accepted
}

// loops.csv as run / detect write it, read back whatever it holds: an image name with a comma or a
// quote is a quoted field (RFC 4180), a BOM and CR-only line ends read as "\n" files do.
TEST(ReadDetections, QuotedImageNamesBomAndCrOnlyLinesReadBack) {
  const auto dir = test::TempDir();
  const auto path = dir / "loops.csv";
  std::ofstream(path, std::ios::binary)
      << "\xEF\xBB\xBFquery,match,score,query_image,match_image\r"
      << "5,1,0.5,\"a,b.png\",\"say \"\"hi\"\".png\"\r6,2,0.25,c.png,d.png\r";
  const auto d = ReadDetections(path);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].query, 5);
  EXPECT_EQ(d[0].score, 0.5);
  EXPECT_EQ(d[1].query, 6);
  EXPECT_EQ(d[1].match, 2);
}

// A quoted image name holding a line end (as CsvField writes it) continues on the next physical
// line; a row after it is numbered by its own first line in errors.
TEST(ReadDetections, AQuotedNameMaySpanLines) {
  const auto dir = test::TempDir();
  const auto path = dir / "loops.csv";
  std::ofstream(path, std::ios::binary) << "query,match,score,query_image,match_image\n"
                                        << "5,1,0.5,\"two\nlines.png\",b.png\n"
                                        << "6,2,0.25,\"a\r\n\"\"b\"\"\n.png\",d.png\n"
                                        << "7,x,0.1,e.png,f.png\n";
  try {
    ReadDetections(path);
    ADD_FAILURE() << "no error";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 7) << e.what();  // the row of frame 7 starts on line 7
    EXPECT_NE(std::string(e.what()).find("'x'"), std::string::npos) << e.what();
  }
  std::ofstream(path, std::ios::binary) << "query,match,score,query_image,match_image\n"
                                        << "5,1,0.5,\"two\nlines.png\",b.png\n"
                                        << "6,2,0.25,\"a\r\n\"\"b\"\"\n.png\",d.png\n";
  const auto d = ReadDetections(path);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].query, 5);
  EXPECT_EQ(d[1].query, 6);
  EXPECT_EQ(d[1].match, 2);
  // An unclosed quote at the end of the file is a row with too few fields, not a hang.
  std::ofstream(path, std::ios::binary) << "query,match,score,query_image,match_image\n"
                                        << "5,1,0.5,\"open.png,b.png\n";
  EXPECT_THROW(ReadDetections(path), FileError);
}

TEST(ReadDetections, ReadsTheAcceptedColumnEmptyMeaningNot) {
  const auto dir = test::TempDir();
  const auto path = dir / "loops.csv";
  std::ofstream(path) << "query,match,score,accepted\n5,1,0.5,1\n6,1,0.4,0\n7,1,0.3,\n";
  const auto d = ReadDetections(path);
  ASSERT_EQ(d.size(), 3u);
  EXPECT_TRUE(d[0].accepted);
  EXPECT_FALSE(d[1].accepted);
  EXPECT_FALSE(d[2].accepted);  // a loop into an earlier session: not in this run's graph
  std::ofstream(path) << "query,match,score,accepted\n5,1,0.5,yes\n";
  try {
    ReadDetections(path);
    ADD_FAILURE() << "no error";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(std::string(e.what()).find("accepted"), std::string::npos) << e.what();
  }
}

// A straight line x = frame (1 m per frame), then frames 10..14 come back to x = 0..4.
Trajectory LineThenBack(bool timestamps = false) {
  Trajectory t;
  t.has_timestamps = timestamps;
  for (int i = 0; i < 15; ++i) {
    StampedPose p;
    p.frame = i;
    p.timestamp = timestamps ? 100.0 + 0.1 * i : i;
    p.world_from_cam.translation = Eigen::Vector3d(i < 10 ? i : i - 10, i < 10 ? 0.0 : 0.5, 0);
    t.poses.push_back(p);
  }
  return t;
}

TEST(ClassifyLoopsByGtDistance, ByFrameIdAndByTimestamp) {
  const Trajectory gt = LineThenBack();
  const std::vector<LoopPair> loops = {{10, 0}, {9, 1}, {42, 1}};
  const LoopTruth t = ClassifyLoopsByGtDistance(loops, gt, 1.0);
  ASSERT_EQ(t.correct.size(), 3u);
  EXPECT_EQ(t.correct[0], std::optional<bool>(true));   // 0.5 apart
  EXPECT_EQ(t.correct[1], std::optional<bool>(false));  // 8 apart
  EXPECT_FALSE(t.correct[2].has_value());               // no GT pose for frame 42
  EXPECT_EQ(t.num_correct(), 1u);
  EXPECT_EQ(t.num_false(), 1u);
  EXPECT_EQ(t.threshold, 1.0);
  // Default threshold: 5 % of the GT path length (capped at 10).
  const auto path = gt.CumulativeDistances();
  EXPECT_DOUBLE_EQ(ClassifyLoopsByGtDistance(loops, gt, 0.0).threshold, 0.05 * path.back());

  // By timestamp: frame 10's time (from `frame_times`) is GT pose 14's, 4 m from frame 0; by
  // frame id the same loop is 0.5 m apart.
  const Trajectory gt_timed = LineThenBack(true);
  Trajectory frame_times;
  frame_times.has_timestamps = true;
  for (const auto& [frame, time] : {std::pair<int64_t, double>{0, 100.0}, {10, 101.4}}) {
    StampedPose p;
    p.frame = frame;
    p.timestamp = time;
    frame_times.poses.push_back(p);
  }
  EXPECT_EQ(ClassifyLoopsByGtDistance({{10, 0}}, gt_timed, 1.0).correct[0],
            std::optional<bool>(true));
  EXPECT_EQ(ClassifyLoopsByGtDistance({{10, 0}}, gt_timed, 1.0, {&frame_times, 0.02}).correct[0],
            std::optional<bool>(false));
  // A frame time with no GT pose within max_dt: no verdict.
  frame_times.poses[1].timestamp = 105.0;
  EXPECT_FALSE(ClassifyLoopsByGtDistance({{10, 0}}, gt_timed, 1.0, {&frame_times, 0.02})
                   .correct[0]
                   .has_value());
}

TEST(ScoreLoopsByGtDistance, HandWorkedVerdictsRecallAndEvents) {
  const Trajectory gt = LineThenBack();
  // GT queries: 10..14 (each back within 1 m of a first-pass frame); one event.
  GtLoopOptions revisit;
  revisit.distance = 1.0;
  revisit.min_gap = 1;
  revisit.min_path = 5.0;
  const auto gt_loops = DeriveGtLoops(gt, revisit);
  ASSERT_FALSE(gt_loops.empty());
  std::vector<Detection> d = {
      {10, 0, 0.9, true},   // correct (0.5 m apart, 10.5 m of path between)
      {3, 2, 0.95, true},   // 1 m apart but only 1 m of path: trivial, left out
      {12, 7, 0.8, false},  // 5 m apart: false, not accepted
      {13, 3, 0.7, true},   // correct
      {14, 99, 0.6, true},  // frame 99 has no GT pose
      {11, 8, 0.5, true},   // false, accepted
  };
  GtDistanceScoringOptions o;
  o.correct_distance = 1.5;
  o.trivial_path = 5.0;
  const GtDistanceScore s = ScoreLoopsByGtDistance(d, gt_loops, gt, o);
  using V = LoopVerdict;
  EXPECT_EQ(s.verdicts, (std::vector<V>{V::kCorrect, V::kTrivial, V::kFalse, V::kCorrect, V::kNoGt,
                                        V::kFalse}));
  EXPECT_EQ(s.trivial, 1u);
  EXPECT_EQ(s.no_gt, 1u);
  EXPECT_EQ(s.all.num_detections, 4u);
  EXPECT_EQ(s.all.true_positives, 2u);
  EXPECT_EQ(s.all.false_positives, 2u);
  EXPECT_EQ(s.all.num_gt_queries, 5u);
  // Sorted by score: 10 (ok), 12 (false) -> recall at 100 % precision 1/5.
  ASSERT_TRUE(s.all.recall_at_100p.has_value());
  EXPECT_DOUBLE_EQ(*s.all.recall_at_100p, 0.2);
  // Accepted only: 10, 13 (both correct), then 11 (false) -> 2/5.
  EXPECT_EQ(s.accepted.num_detections, 3u);
  EXPECT_EQ(s.accepted.false_positives, 1u);
  EXPECT_DOUBLE_EQ(*s.accepted.recall_at_100p, 0.4);
  EXPECT_EQ(s.events, 1u);
  EXPECT_EQ(s.events_detected, 1u);
  // Without the trivial rule the (3, 2) detection is correct but recalls no GT query.
  o.trivial_path = 0.0;
  const GtDistanceScore s0 = ScoreLoopsByGtDistance(d, gt_loops, gt, o);
  EXPECT_EQ(s0.verdicts[1], V::kCorrect);
  EXPECT_EQ(s0.trivial, 0u);
  EXPECT_DOUBLE_EQ(*s0.all.recall_at_100p, 0.2);
  // No accepted correct detection: the event is not detected.
  for (auto& x : d) x.accepted = false;
  EXPECT_EQ(ScoreLoopsByGtDistance(d, gt_loops, gt, o).events_detected, 0u);
  o.correct_distance = 0.0;
  EXPECT_THROW(ScoreLoopsByGtDistance(d, gt_loops, gt, o), std::invalid_argument);
}

TEST(ScoreLoopsByGtDistance, TwoEventsSplitByTheEventGap) {
  const std::vector<LoopPair> gt_loops = {{100, 1}, {105, 2}, {130, 3}, {131, 4}};
  Trajectory gt;
  for (int i = 0; i < 140; ++i) {
    StampedPose p;
    p.frame = i;
    gt.poses.push_back(p);  // every frame at the origin: every detection is correct
  }
  GtDistanceScoringOptions o;
  o.correct_distance = 1.0;
  o.event_gap = 10;
  o.event_margin = 2;
  // 133 is within the margin of the second event [130, 131]; 97 is not within 2 of [100, 105].
  const auto s = ScoreLoopsByGtDistance({{133, 3, 1.0, true}, {97, 1, 0.9, true}}, gt_loops, gt, o);
  EXPECT_EQ(s.events, 2u);
  EXPECT_EQ(s.events_detected, 1u);
  o.event_gap = 30;  // one event [100, 131]
  EXPECT_EQ(ScoreLoopsByGtDistance({{97, 1, 1.0, true}}, gt_loops, gt, o).events, 1u);
}

TEST(ReadDetections, MalformedFilesNameFileAndLine) {
  const auto dir = test::TempDir();
  auto expect_error = [&](const std::string& content, int line, const std::string& what) {
    const auto path = dir / "bad.csv";
    {
      std::ofstream out(path);
      out << content;
    }
    try {
      ReadDetections(path);
      ADD_FAILURE() << "no error for: " << content;
    } catch (const FileError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.csv"), std::string::npos) << e.what();
    }
  };
  expect_error("query,match\n1,2\n", 1, "score");
  expect_error("query,match,score\n1,2,0.5\n3,4\n", 3, "3 comma-separated fields");
  expect_error("query,match,score\n1,2,0.5\n\nx,4,0.1\n", 4, "query");
  expect_error("query,match,score\n1,2,nan\n", 2, "score");
  expect_error("", 0, "header");
  EXPECT_THROW(ReadDetections(dir / "missing.csv"), FileError);
}

TEST(IdRanges, FormatParseRoundTripAndRejectsMalformedText) {
  EXPECT_EQ(FormatIdRanges({14, 3, 10, 11, 12, 13, 20, 3}), "3;10-14;20");
  EXPECT_EQ(FormatIdRanges({}), "");
  EXPECT_EQ(FormatIdRanges({7}), "7");
  std::vector<int64_t> ids;
  ASSERT_TRUE(ParseIdRanges("3;10-14;20", &ids));
  EXPECT_EQ(ids, (std::vector<int64_t>{3, 10, 11, 12, 13, 14, 20}));
  ASSERT_TRUE(ParseIdRanges("", &ids));
  EXPECT_TRUE(ids.empty());
  // Random sets survive the round trip exactly.
  std::mt19937 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<int64_t> set;
    for (int64_t v = 0; v < 200; ++v)
      if (rng() % 3 == 0) set.push_back(v);
    ASSERT_TRUE(ParseIdRanges(FormatIdRanges(set), &ids));
    EXPECT_EQ(ids, set);
  }
  for (const char* bad : {"a", "3;", "5-3", "3;3", "4;2", "1-2-3", "-1", ";", "1,2"})
    EXPECT_FALSE(ParseIdRanges(bad, &ids)) << bad;
}

TEST(SearchAreaCoverage, CountsGtQueriesWithAGtMatchInTheirArea) {
  // GT queries 50 (matches 1, 2), 51 (match 3), 52 (match 4), 60 (no frames.csv row).
  const std::vector<LoopPair> gt = {{50, 1}, {50, 2}, {51, 3}, {52, 4}, {60, 5}};
  std::map<int64_t, std::vector<int64_t>> areas;
  areas[50] = {2, 7, 8};  // one of its two GT matches: covered
  areas[51] = {1, 2};     // another query's match only: not covered
  areas[52] = {};         // nothing searched
  areas[53] = {4};        // not a GT query: ignored
  const AreaCoverage c = SearchAreaCoverage(gt, areas);
  EXPECT_EQ(c.queries, 3u);
  EXPECT_EQ(c.covered, 1u);
  ASSERT_TRUE(c.fraction);
  EXPECT_DOUBLE_EQ(*c.fraction, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.mean_candidates, 5.0 / 3.0);
  EXPECT_FALSE(SearchAreaCoverage(gt, {}).fraction);
}

TEST(ReadSearchAreas, ReadsTheAreaColumnAndNamesFileAndLine) {
  const auto dir = test::TempDir();
  const auto path = dir / "frames.csv";
  std::ofstream(path) << "frame,status,area\n0,no_candidates,\n7,detected,1-3;5\n";
  const auto areas = ReadSearchAreas(path);
  ASSERT_EQ(areas.size(), 2u);
  EXPECT_TRUE(areas.at(0).empty());
  EXPECT_EQ(areas.at(7), (std::vector<int64_t>{1, 2, 3, 5}));
  const auto expect_error = [&](const std::string& content, int line, const std::string& what) {
    std::ofstream(path) << content;
    try {
      ReadSearchAreas(path);
      ADD_FAILURE() << "no error for: " << content;
    } catch (const FileError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("frames.csv"), std::string::npos) << e.what();
    }
  };
  expect_error("frame,status\n0,x\n", 1, "area");
  expect_error("frame,area\n0,3-1\n", 2, "ranges");
  expect_error("frame,area\nx,1\n", 2, "frame id");
  expect_error("frame,area\n0,1,2\n", 2, "2 comma-separated fields");
  EXPECT_THROW(ReadSearchAreas(dir / "missing.csv"), FileError);
}

}  // namespace
}  // namespace sparseloop
