// rtabmap corridor: no poses (global search), unknown intrinsics (guessed), GT loop matrix.
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "real_data.h"
#include "sparseloop/loop/loop_detector.h"
#include "test_util.h"

namespace sparseloop {
namespace {

struct PrNumbers {
  int detections = 0;
  int true_positives = 0;
  int queries_with_gt = 0;
  double precision = 1.0;
  double recall = 0.0;
  double recall_at_full_precision = 0.0;
};

PrNumbers RunRtabmap(const std::vector<cv::Mat>& images, const std::set<std::pair<int, int>>& gt,
                     LoopDetector::Options options) {
  options.search.strategy = SearchStrategy::kGlobal;  // no poses: documented input choice
  LoopDetector detector(options);
  std::vector<std::pair<double, bool>> scored;
  std::set<int> queries_with_gt;
  for (const auto& [q, m] : gt) queries_with_gt.insert(q);
  PrNumbers pr;
  for (size_t i = 0; i < images.size(); ++i) {
    KeyframeInput in;
    in.id = static_cast<int64_t>(i);
    in.timestamp = static_cast<double>(in.id);  // keyframe timestamps must increase
    in.image = images[i];
    in.intrinsics = test::GuessIntrinsics(images[i].cols, images[i].rows);
    const LoopResult r = detector.Process(in);
    if (!r.detected()) continue;
    const bool ok = gt.count({int(r.query_id), int(r.match_id)}) > 0;
    scored.emplace_back(r.score, ok);
    ++pr.detections;
    pr.true_positives += ok;
    if (!ok)
      std::printf("  false loop %lld -> %lld (inliers %d)\n", (long long)r.query_id + 1,
                  (long long)r.match_id + 1, r.inliers);
  }
  pr.queries_with_gt = static_cast<int>(queries_with_gt.size());
  pr.precision = pr.detections ? double(pr.true_positives) / pr.detections : 1.0;
  pr.recall = double(pr.true_positives) / pr.queries_with_gt;
  std::stable_sort(scored.begin(), scored.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  int tp = 0;
  for (size_t i = 0; i < scored.size(); ++i) {
    if (!scored[i].second) break;
    tp += 1;
    // Only cut between distinct scores.
    if (i + 1 == scored.size() || scored[i + 1].first != scored[i].first)
      pr.recall_at_full_precision = double(tp) / pr.queries_with_gt;
  }
  return pr;
}

TEST(RtabmapCorridor, PrecisionAndRecallOverK) {
  SL_REQUIRE_DATA("rtabmap_corridor_loop");
  const auto images = test::LoadRtabmap();
  std::set<std::pair<int, int>> gt;
  for (const auto& p : test::LoadRtabmapGt()) gt.insert(p);
  ASSERT_EQ(gt.size(), 228u);
  double best_recall = 0;
  for (int k : {15, 50, 100, 300}) {
    LoopDetector::Options options;
    options.features.max_features = k;
    const PrNumbers pr = RunRtabmap(images, gt, options);
    std::printf(
        "rtabmap K=%3d: detections %2d TP %2d precision %.3f recall %.3f "
        "recall@100%%P %.3f (of %d queries)\n",
        k, pr.detections, pr.true_positives, pr.precision, pr.recall, pr.recall_at_full_precision,
        pr.queries_with_gt);
    EXPECT_EQ(pr.precision, 1.0) << "K=" << k;
    best_recall = std::max(best_recall, pr.recall_at_full_precision);
    // K = 15, the paper's K, without a pose prior: 0.02 with the K >= 30 floors (12 matches, 12
    // inliers), 0.30 with the small-K floors (8 / 8; docs/DETECTOR.md, "Small K").
    if (k == 15) {
      EXPECT_GE(pr.recall_at_full_precision, 0.25);
    }
  }
  EXPECT_GE(best_recall, 0.9);
}

// Sparse K = 15 without poses (no gate, no search area: the hardest case for a small K):
// asymmetric matching, repeatability ranking and weak pairs confirmed by the keyframe before,
// one at a time and together, beside the symmetric K = 15 of the paper (numbers in
// docs/DETECTOR.md, "Sparse K = 15"). Asymmetric matching alone keeps precision 1 and doubles
// recall; repeatability ranking finds more but on this corridor keeps the repeated structure
// (door frames, ceiling lights) and brings false loops, which no pose gate stops here.
TEST(RtabmapCorridor, SparseK15Variants) {
  SL_REQUIRE_DATA("rtabmap_corridor_loop");
  const auto images = test::LoadRtabmap();
  std::set<std::pair<int, int>> gt;
  for (const auto& p : test::LoadRtabmapGt()) gt.insert(p);
  struct Variant {
    const char* name;
    bool asymmetric;
    int window;
    int weak;
  };
  std::map<std::string, PrNumbers> got;
  for (const Variant& v : {Variant{"symmetric", false, 0, 0}, Variant{"asymmetric", true, 0, 0},
                           Variant{"weak", false, 0, 6}, Variant{"repeatability", false, 2, 0},
                           Variant{"asym+weak", true, 0, 6}, Variant{"asym+rep", true, 2, 0},
                           Variant{"rep4+weak", false, 4, 6}}) {
    LoopDetector::Options options;
    options.features.max_features = 15;
    options.asymmetric_matching = v.asymmetric;
    options.repeatability_window = v.window;
    options.weak_pairs = v.weak > 0;
    if (v.weak > 0) options.weak_min_inliers = v.weak;
    const PrNumbers pr = RunRtabmap(images, gt, options);
    std::printf("rtabmap K=15 %-14s detections %2d TP %2d precision %.3f recall@100%%P %.3f\n",
                v.name, pr.detections, pr.true_positives, pr.precision,
                pr.recall_at_full_precision);
    got[v.name] = pr;
  }
  EXPECT_EQ(got["asymmetric"].precision, 1.0);
  EXPECT_GE(got["asymmetric"].recall_at_full_precision, 0.6);  // symmetric: 0.295
  EXPECT_GE(got["asymmetric"].recall_at_full_precision,
            got["symmetric"].recall_at_full_precision + 0.25);
  EXPECT_EQ(got["weak"].precision, 1.0);
  EXPECT_GT(got["weak"].recall_at_full_precision, got["symmetric"].recall_at_full_precision);
}

// Small K without poses, at K = 20 (asymmetric matching, weak pairs with agreement):
// every candidate verified and the most inliers kept (Options::best_of_verified; the first
// passing one was 47 -> 10, 9 inliers, where 47 -> 9 has 10: the GT has 47 -> 5..9). The
// recall@100%P target is 0.88; the single-pair oracle at K = 20 is 0.909
// (docs/DETECTOR.md, "The corridor at K = 15-20 without poses").
TEST(RtabmapCorridor, SmallKWithoutPoses) {
  SL_REQUIRE_DATA("rtabmap_corridor_loop");
  const auto images = test::LoadRtabmap();
  std::set<std::pair<int, int>> gt;
  for (const auto& p : test::LoadRtabmapGt()) gt.insert(p);
  LoopDetector::Options options;
  options.features.max_features = 20;
  options.asymmetric_matching = true;
  options.weak_pairs = true;
  const PrNumbers pr = RunRtabmap(images, gt, options);
  std::printf(
      "rtabmap K=20 asymmetric + weak: detections %2d TP %2d precision %.3f "
      "recall@100%%P %.3f\n",
      pr.detections, pr.true_positives, pr.precision, pr.recall_at_full_precision);
  EXPECT_EQ(pr.precision, 1.0);
  EXPECT_GE(pr.recall_at_full_precision, 0.88);
  options.best_of_verified = false;  // the premise: the first passing candidate is not the best
  const PrNumbers first = RunRtabmap(images, gt, options);
  EXPECT_LT(first.precision, 1.0);
}

}  // namespace
}  // namespace sparseloop
