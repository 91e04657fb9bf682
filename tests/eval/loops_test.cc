#include "sparseloop/eval/loops.h"

#include <algorithm>
#include <fstream>
#include <numbers>

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

}  // namespace
}  // namespace sparseloop
