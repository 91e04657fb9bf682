// Detector behaviour without real data: options, statuses, every-N rule, determinism.
#include <algorithm>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "cameras.h"
#include "sparseloop/loop/loop_detector.h"
#include "test_util.h"

namespace sparseloop {
namespace {

cv::Mat Textured(uint64_t seed) {
  cv::Mat img(240, 320, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  for (int i = 0; i < 60; ++i)
    cv::circle(img, cv::Point(rng.uniform(0, 320), rng.uniform(0, 240)), rng.uniform(3, 15),
               cv::Scalar(rng.uniform(0, 255)), cv::FILLED);
  return img;
}

CameraIntrinsics Camera() { return test::SmallCamera(); }

LoopDetector::Options GlobalNoExclusion() {
  LoopDetector::Options o;
  o.search.strategy = SearchStrategy::kGlobal;
  o.search.exclude_recent = 0;
  o.min_path_ratio = 0;
  o.overlap_gap = 0;  // no overlap walk either: these tests revisit the frame just before
  return o;
}

// The image shifted by a few pixels: an identical image has no parallax (degenerate for the
// essential matrix), a shifted one verifies like a small camera motion.
cv::Mat Shifted(const cv::Mat& a) {
  cv::Mat out;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 6, 0, 1, -4);
  cv::warpAffine(a, out, shift, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  return out;
}

// `image` with `count` black / white rectangles (sides in [min_side, max_side) px) whose corners
// lie in `area`: strong corners that are not part of the scene.
cv::Mat WithBlobs(cv::Mat image, int count, cv::Rect area, int min_side, int max_side,
                  uint64_t seed) {
  cv::RNG rng(seed);
  for (int i = 0; i < count; ++i) {
    const cv::Point c(rng.uniform(area.x, area.x + area.width),
                      rng.uniform(area.y, area.y + area.height));
    cv::rectangle(image, c,
                  c + cv::Point(rng.uniform(min_side, max_side), rng.uniform(min_side, max_side)),
                  cv::Scalar(i % 2 ? 255 : 0), cv::FILLED);
  }
  return image;
}

// 18 keyframes: 17 different places, and last the place of keyframe 1 seen again (Shifted).
std::vector<cv::Mat> RevisitOfKeyframeOne() {
  const cv::Mat place = Textured(41);
  std::vector<cv::Mat> frames = {Textured(42), place};
  for (uint64_t seed = 43; seed < 58; ++seed) frames.push_back(Textured(seed));
  frames.push_back(Shifted(place));
  return frames;
}

// A radius search area (the keyframes within `radius` of the query; no uncertainty area), 2
// recent excluded, no path-length filter.
LoopDetector::Options RadiusSearch(double radius) {
  LoopDetector::Options o;
  o.search.strategy = SearchStrategy::kRadius;
  o.search.radius = radius;
  o.search.drift_rate = 0.0;
  o.search.exclude_recent = 2;
  o.min_path_ratio = 0;
  return o;
}

KeyframeInput Input(int64_t id, const cv::Mat& image) {
  KeyframeInput in;
  in.id = id;
  in.timestamp = static_cast<double>(in.id);  // keyframe timestamps must increase
  in.image = image;
  in.intrinsics = Camera();
  return in;
}

// A fresh detector processes `frames` as keyframes 0, 1, ... posed along x, `spacing` apart (raw
// units); the last keyframe's result.
LoopResult LastResultAlongX(const LoopDetector::Options& o, const std::vector<cv::Mat>& frames,
                            double spacing) {
  LoopDetector detector(o);
  LoopResult last;
  for (size_t i = 0; i < frames.size(); ++i) {
    KeyframeInput in = Input(static_cast<int64_t>(i), frames[i]);
    in.world_from_cam = Sim3d(1.0, Eigen::Quaterniond::Identity(),
                              Eigen::Vector3d(spacing * static_cast<double>(i), 0, 0));
    last = detector.Process(in);
  }
  return last;
}

TEST(LoopDetector, OptionsCheck) {
  EXPECT_NO_THROW(LoopDetector::Options{}.Check());
  LoopDetector::Options o;
  o.check_every = 0;
  EXPECT_THROW(LoopDetector detector(o), std::invalid_argument);
  o = {};
  o.consistency_max_deg = 1;  // below base
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = {};
  o.features.max_features = 100;
  o.min_inlier_fraction_of_k = 0.2;
  EXPECT_EQ(o.EffectiveMinInliers(), 20);
  o.features.max_features = 15;
  // Small K: ceil(0.4 * K), not below 8, not above the K >= 30 floors (12).
  EXPECT_EQ(o.EffectiveMinInliers(), 8);
  EXPECT_EQ(o.EffectiveMinMatches(), 8);
  o.features.max_features = 25;
  EXPECT_EQ(o.EffectiveMinInliers(), 10);
  EXPECT_EQ(o.EffectiveMinMatches(), 10);
  o.features.max_features = 30;
  EXPECT_EQ(o.EffectiveMinInliers(), o.verify.min_inliers);
  EXPECT_EQ(o.EffectiveMinMatches(), o.min_matches);
  o.features.max_features = 300;
  o.min_inlier_fraction_of_k = 0.08;
  EXPECT_EQ(o.EffectiveMinInliers(), 24);
  EXPECT_EQ(o.EffectiveMinMatches(), 12);
  o.small_k_floor = 4;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = {};
  o.small_k_fraction = 0;
  EXPECT_THROW(o.Check(), std::invalid_argument);
}

TEST(LoopDetector, NoPoseNeedsGlobalSearchAndIdsAreUnique) {
  // Under a geometric strategy a pose-less keyframe is "tracking lost": it is relocalised
  // (nothing stored with a pose yet, so no candidate) ...
  LoopDetector paper(LoopDetector::Options{});  // default strategy: paper
  const LoopResult lost = paper.Process(Input(0, Textured(1)));
  EXPECT_TRUE(lost.relocalization);
  EXPECT_FALSE(lost.detected());
  EXPECT_FALSE(lost.has_world_from_query);
  // ... and with relocalisation switched off it is a caller error.
  LoopDetector::Options strict;
  strict.relocalize_without_pose = false;
  LoopDetector no_reloc(strict);
  EXPECT_THROW(no_reloc.Process(Input(0, Textured(1))), std::invalid_argument);
  LoopDetector global(GlobalNoExclusion());
  EXPECT_EQ(global.Process(Input(0, Textured(1))).status, LoopStatus::kNoCandidates);
  EXPECT_THROW(global.Process(Input(0, Textured(1))), std::invalid_argument);
}

TEST(LoopDetector, RevisitDetectedUnrelatedNot) {
  LoopDetector detector(GlobalNoExclusion());
  const cv::Mat a = Textured(1), b = Textured(2);
  cv::Mat a_shifted;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 6, 0, 1, -4);
  cv::warpAffine(a, a_shifted, shift, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  EXPECT_EQ(detector.Process(Input(10, a)).status, LoopStatus::kNoCandidates);
  const LoopResult unrelated = detector.Process(Input(11, b));
  EXPECT_FALSE(unrelated.detected()) << ToString(unrelated.status);
  const LoopResult revisit = detector.Process(Input(12, a_shifted));
  ASSERT_TRUE(revisit.detected()) << ToString(revisit.status);
  EXPECT_EQ(revisit.match_id, 10);
  EXPECT_GE(revisit.inliers, detector.options().EffectiveMinInliers());
  EXPECT_GT(revisit.score, 0.0);
  EXPECT_LE(revisit.score, 1.0);
  EXPECT_GE(revisit.timings.total_ms, revisit.timings.extract_ms);
  EXPECT_EQ(detector.num_keyframes(), 3u);
  EXPECT_EQ(detector.StoredBytes(), detector.packed_record(10).Bytes() +
                                        detector.packed_record(11).Bytes() +
                                        detector.packed_record(12).Bytes());
  // The stored record is the packed one: unpacking and packing it again gives its bytes.
  const PackedKeyframe again = PackRecord(detector.record(12));
  EXPECT_TRUE(std::ranges::equal(again.bytes(), detector.packed_record(12).bytes()));
  EXPECT_THROW(detector.record(99), std::invalid_argument);
}

// Asymmetric matching: the stored record is the same K as without it (same bytes,
// same descriptors), while the query matches with its whole extraction. A revisit whose query
// view holds new, stronger corners (here: high-contrast blobs painted over a third of it) keeps
// few of the stored K among its own strongest K: K x K misses it, K x all finds it.
TEST(LoopDetector, AsymmetricMatchingStoresKAndFindsWhatKxKMisses) {
  const cv::Mat a = Textured(1), b = Textured(2);
  const cv::Mat revisit = WithBlobs(Shifted(a), 30, cv::Rect(0, 0, 90, 230), 6, 14, 9);
  auto run = [&](bool asymmetric) {
    LoopDetector::Options o = GlobalNoExclusion();
    o.features.max_features = 15;
    o.asymmetric_matching = asymmetric;
    LoopDetector detector(o);
    detector.Process(Input(0, a));
    detector.Process(Input(1, b));
    const LoopResult r = detector.Process(Input(2, revisit));
    std::vector<KeyframeRecord> stored;
    for (int64_t id : {0, 1, 2}) stored.push_back(detector.record(id));
    return std::make_pair(r, stored);
  };
  const auto [sym, sym_records] = run(false);
  const auto [asym, asym_records] = run(true);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(asym_records[i].size(), 15u);
    EXPECT_EQ(asym_records[i].descriptors, sym_records[i].descriptors) << i;
    EXPECT_EQ(asym_records[i].Bytes(), sym_records[i].Bytes()) << i;
  }
  EXPECT_FALSE(sym.detected()) << ToString(sym.status) << " " << sym.matches;
  ASSERT_TRUE(asym.detected()) << ToString(asym.status) << " " << asym.matches;
  EXPECT_EQ(asym.match_id, 0);
  EXPECT_GT(asym.matches, sym.matches);
  EXPECT_LE(asym.inliers, 15);  // every stored feature matches at most once
  LoopDetector::Options bad;
  bad.query_max_features = 4;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// The overlap walk's buffer at a small K (Options::overlap_features): only keyframes without a
// pose, only when the query is extracted with more than K, at most overlap_window of them, each
// overlap_features descriptors: bounded memory whatever the map's size.
TEST(LoopDetector, OverlapBufferIsBounded) {
  auto buffer_bytes = [](LoopDetector::Options o, bool posed) {
    o.features.max_features = 15;
    o.asymmetric_matching = true;
    o.overlap_features = 100;
    o.overlap_window = 5;
    if (!posed) o.search.strategy = SearchStrategy::kGlobal;
    LoopDetector detector(o);
    for (int64_t i = 0; i < 12; ++i) {
      KeyframeInput in = Input(i, Textured(100 + static_cast<uint64_t>(i)));
      if (posed)
        in.world_from_cam = Sim3d(1.0, Eigen::Quaterniond::Identity(),
                                  Eigen::Vector3d(static_cast<double>(i), 0, 0));
      detector.Process(in);
    }
    return detector.RecentBufferBytes();
  };
  LoopDetector::Options o;
  EXPECT_EQ(buffer_bytes(o, false), 5u * 100u * sizeof(Descriptor));
  EXPECT_EQ(buffer_bytes(o, true), 0u);  // with poses the walk does not run
  LoopDetector::Options off;
  off.overlap_gap = 0;  // no walk: no buffer
  EXPECT_EQ(buffer_bytes(off, false), 0u);
  LoopDetector::Options bad;
  bad.overlap_window = 0;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
  bad = {};
  bad.overlap_features = -1;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// Repeatability ranking: a keyframe stores first the features the keyframe before
// re-finds. Keyframe 1 is keyframe 0 moved a little plus transient high-contrast blobs (strong
// corners that no other keyframe sees): ranked by response its K are mostly blob corners, ranked
// by repeatability they are structure keyframe 0 also saw, and keyframe 2 (the same place again,
// without blobs) matches more of them.
TEST(LoopDetector, RepeatabilityRankingStoresWhatTheKeyframeBeforeSaw) {
  const cv::Mat a = Textured(4);
  const cv::Mat transient = WithBlobs(Shifted(a), 40, cv::Rect(0, 0, 310, 230), 5, 9, 21);
  // Keyframes with raw poses (repeatability ranks only those, see below).
  auto stored_of_1 = [&](int window, bool posed) {
    LoopDetector::Options o = GlobalNoExclusion();
    o.features.max_features = 15;
    o.repeatability_window = window;
    LoopDetector detector(o);
    KeyframeInput first = Input(0, a), second = Input(1, transient);
    if (posed) {
      first.world_from_cam = Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
      second.world_from_cam =
          Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, 0, 0));
    }
    detector.Process(first);
    detector.Process(second);
    return detector.record(1);
  };
  const KeyframeRecord response = stored_of_1(0, true), repeatable = stored_of_1(1, true);
  ASSERT_EQ(response.size(), 15u);
  ASSERT_EQ(repeatable.size(), 15u);
  // Without a pose the stored K keep the extraction's own ranking: the features that persist
  // longest would defeat the overlap walk, the only guard against the view still ahead
  // (kitti07_first160 without poses, K = 20: 8 false loops with them, 0 without).
  const KeyframeRecord unposed = stored_of_1(1, false);
  EXPECT_EQ(unposed.descriptors, stored_of_1(0, false).descriptors);
  EXPECT_NE(unposed.descriptors, repeatable.descriptors);
  // How many of the stored 15 a later clean view of the place finds (asymmetric, 1,000).
  LoopDetector::Options wide = GlobalNoExclusion();
  wide.asymmetric_matching = true;
  wide.features.max_features = 15;
  const cv::Mat later = Shifted(Shifted(a));
  auto refound = [&](const KeyframeRecord& stored) {
    KeyframeInput in = Input(0, later);
    LoopDetector::Options o = wide;
    o.features.max_features = 1000;
    o.features.orb_candidates = 1000;
    LoopDetector extract(o);
    extract.Process(in);
    return MatchStoredIntoQuery(extract.record(0).descriptors, stored.descriptors, o.match).size();
  };
  const size_t by_response = refound(response), by_repeatability = refound(repeatable);
  EXPECT_GE(by_repeatability, 8u);
  EXPECT_GE(by_repeatability, by_response + 4) << by_response;
  LoopDetector::Options bad;
  bad.repeatability_window = -1;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
  bad.repeatability_window = 2;
  bad.repeatability_pool = 3;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// A place seen twice (0, 1), four other places, then the place again in two keyframes (6: a
// revisit of 0 / 1, 7: of 1 / 0).
std::vector<cv::Mat> RevisitInTwoKeyframes() {
  const cv::Mat place = Textured(31);
  std::vector<cv::Mat> frames = {place, Shifted(place)};
  for (uint64_t seed : {32, 33, 34, 35}) frames.push_back(Textured(seed));
  frames.push_back(Shifted(Shifted(place)));
  frames.push_back(Shifted(Shifted(Shifted(place))));
  return frames;
}

// Weak pairs: with the inlier floor at K (so every real pair here is weak),
// the first keyframe of a revisit is verified but unconfirmed (kRejectedByTemporal), the second,
// whose match is next to the first's, is confirmed by it and detected; an isolated weak pair is
// never detected. Without weak pairs neither is detected (too few matches for the K floor).
TEST(LoopDetector, WeakPairsNeedTheAgreementOfTheKeyframeBefore) {
  std::vector<cv::Mat> frames = RevisitInTwoKeyframes();
  frames.push_back(Textured(36));
  size_t anchors = 0;
  auto run = [&](int weak, int floor) {
    LoopDetector::Options o = GlobalNoExclusion();
    o.search.exclude_recent = 3;
    o.features.max_features = 15;
    o.small_k_floor = floor;  // 15 = K: every pair below is weak
    o.weak_pairs = weak > 0;
    if (weak > 0) o.weak_min_inliers = weak;
    LoopDetector detector(o);
    std::vector<LoopResult> out;
    for (size_t i = 0; i < frames.size(); ++i)
      out.push_back(detector.Process(Input(static_cast<int64_t>(i), frames[i])));
    anchors = detector.num_anchor_loops();
    return out;
  };
  const auto strict = run(0, 15);
  EXPECT_FALSE(strict[6].detected()) << ToString(strict[6].status);
  EXPECT_FALSE(strict[7].detected()) << ToString(strict[7].status);
  // At the usual floor the revisit is a loop at the floor, and it anchors the rotation prior and
  // the search area of what follows.
  const auto usual = run(6, 8);
  ASSERT_TRUE(usual[7].detected()) << ToString(usual[7].status);
  EXPECT_GE(usual[7].inliers, 8);
  EXPECT_GE(anchors, 1u);
  const auto weak = run(6, 15);
  // A weak loop is a loop, but no anchor: its pose rests on a handful of inliers.
  EXPECT_EQ(anchors, 0u);
  EXPECT_EQ(weak[6].status, LoopStatus::kRejectedByTemporal) << ToString(weak[6].status);
  EXPECT_GE(weak[6].inliers, 6);
  ASSERT_EQ(weak[7].status, LoopStatus::kDetected) << ToString(weak[7].status);
  EXPECT_LE(weak[7].match_id, 1);
  EXPECT_LT(weak[7].inliers, 15);
  for (size_t i = 0; i < 6; ++i) EXPECT_FALSE(weak[i].detected()) << i;
  EXPECT_FALSE(weak[8].detected());
  LoopDetector::Options bad;
  bad.weak_pairs = true;
  bad.weak_min_inliers = 4;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
  bad.weak_min_inliers = 6;
  bad.agreement_window = 0;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// A search area of radius 1 raw unit alone (no uncertainty area, no path-ratio filter): a revisit
// whose raw pose drifted away lies outside it.
LoopDetector::Options RadiusOnly(SearchStrategy strategy, int exclude_recent) {
  LoopDetector::Options o;
  o.search.strategy = strategy;
  o.search.radius = 1.0;
  o.search.exclude_recent = exclude_recent;
  o.search.drift_rate = 0.0;
  o.min_path_ratio = 0;
  return o;
}

// Appearance fallback: the drifted raw pose puts the revisit far from its first visit,
// so the search area (a radius here) holds no candidate; the fallback ranks every stored keyframe
// and finds the same loop as a global (brute-force) search does, reported as kAppearance.
TEST(LoopDetector, AppearanceFallbackFindsWhatGlobalSearchFinds) {
  const cv::Mat place = Textured(1);
  std::vector<cv::Mat> frames = {place};
  for (uint64_t seed : {2, 3, 4, 5, 6}) frames.push_back(Textured(seed));
  frames.push_back(Shifted(place));  // 6: the revisit of 0
  auto run = [&](SearchStrategy strategy, bool fallback) {
    LoopDetector::Options o = RadiusOnly(strategy, 2);
    o.appearance_fallback = fallback;
    LoopDetector detector(o);
    LoopResult last;
    for (size_t i = 0; i < frames.size(); ++i) {
      KeyframeInput in = Input(static_cast<int64_t>(i), frames[i]);
      // Out along x, the revisit drifted 50 m sideways of frame 0's raw position.
      in.world_from_cam =
          i < 6 ? Sim3d(1.0, Eigen::Quaterniond::Identity(),
                        Eigen::Vector3d(100.0 * static_cast<double>(i), 0, 0))
                : Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 50, 0));
      last = detector.Process(in);
    }
    return last;
  };
  const LoopResult area = run(SearchStrategy::kRadius, false);
  EXPECT_EQ(area.status, LoopStatus::kNoCandidates) << ToString(area.status);
  const LoopResult fallback = run(SearchStrategy::kRadius, true);
  const LoopResult global = run(SearchStrategy::kGlobal, false);
  ASSERT_TRUE(global.detected()) << ToString(global.status);
  ASSERT_TRUE(fallback.detected()) << ToString(fallback.status);
  EXPECT_EQ(fallback.source, CandidateSource::kAppearance);
  EXPECT_EQ(global.source, CandidateSource::kSearchArea);
  EXPECT_EQ(fallback.match_id, 0);
  EXPECT_EQ(fallback.match_id, global.match_id);
  EXPECT_EQ(fallback.matches, global.matches);
  EXPECT_EQ(fallback.inliers, global.inliers);
  EXPECT_STREQ(ToString(CandidateSource::kAppearance), "appearance");
  // Which keyframes were verified, and by which search: the loop stops at its match.
  EXPECT_TRUE(area.verified_in_area.empty());
  EXPECT_TRUE(area.verified_by_appearance.empty());
  EXPECT_TRUE(fallback.verified_in_area.empty());
  EXPECT_EQ(fallback.verified_by_appearance, std::vector<int64_t>{0});
  ASSERT_FALSE(global.verified_in_area.empty());
  EXPECT_EQ(global.verified_in_area.back(), global.match_id);
  EXPECT_LE(global.verified_in_area.size(), 3u);  // max_verify
  EXPECT_TRUE(global.verified_by_appearance.empty());
}

// Outside the search area the raw trajectory vouches for nothing, so the appearance fallback
// takes no weak pair: the revisit of WeakPairsNeedTheAgreementOfTheKeyframeBefore (weak, confirmed
// by the keyframe before), posed far from its first visit, is a loop when the area holds it
// (global search) and none when only the fallback reaches it.
TEST(LoopDetector, AppearanceFallbackTakesNoWeakPairs) {
  const std::vector<cv::Mat> frames = RevisitInTwoKeyframes();
  auto run = [&](SearchStrategy strategy) {
    LoopDetector::Options o = RadiusOnly(strategy, 3);
    o.features.max_features = 15;
    o.small_k_floor = 15;  // floor = K: every pair below is weak
    o.weak_pairs = true;
    o.appearance_fallback = true;
    LoopDetector detector(o);
    std::vector<LoopResult> out;
    for (size_t i = 0; i < frames.size(); ++i) {
      KeyframeInput in = Input(static_cast<int64_t>(i), frames[i]);
      in.world_from_cam = i < 6 ? Sim3d(1.0, Eigen::Quaterniond::Identity(),
                                        Eigen::Vector3d(100.0 * static_cast<double>(i), 0, 0))
                                : Sim3d(1.0, Eigen::Quaterniond::Identity(),
                                        Eigen::Vector3d(0.1 * static_cast<double>(i - 6), 50, 0));
      out.push_back(detector.Process(in));
    }
    return out;
  };
  const auto global = run(SearchStrategy::kGlobal);
  ASSERT_TRUE(global[7].detected()) << ToString(global[7].status);
  EXPECT_LT(global[7].inliers, 15);  // weak
  const auto fallback = run(SearchStrategy::kRadius);
  EXPECT_GT(fallback[7].appearance_candidates, 0);
  EXPECT_FALSE(fallback[6].detected()) << ToString(fallback[6].status);
  EXPECT_FALSE(fallback[7].detected()) << ToString(fallback[7].status);
}

// The fallback's pre-ranking (fallback_candidates): among 14 eligible stored keyframes, only the
// 2 best by the cheap score are matched in full and verified, and the loop is the one the full
// fallback (every eligible keyframe matched, the brute-force reference) finds, with the same
// matches and inliers. The revisit's place is stored second (id 1) so the pre-ranking, not the
// id order, has to bring it forward.
TEST(LoopDetector, AppearanceFallbackPreRankingKeepsTheLoopOfTheFullFallback) {
  const std::vector<cv::Mat> frames = RevisitOfKeyframeOne();
  auto run = [&](int candidates) {
    LoopDetector::Options o = RadiusSearch(1.0);
    o.appearance_fallback = true;
    o.fallback_candidates = candidates;
    return LastResultAlongX(o, frames, 100.0);
  };
  const LoopResult full = run(0);
  const LoopResult ranked = run(2);
  const int eligible = static_cast<int>(frames.size()) - 1 - 2;  // older than exclude_recent
  ASSERT_TRUE(full.detected()) << ToString(full.status);
  ASSERT_TRUE(ranked.detected()) << ToString(ranked.status);
  EXPECT_EQ(full.appearance_candidates, eligible);
  EXPECT_EQ(ranked.appearance_candidates, 2);
  EXPECT_EQ(ranked.source, CandidateSource::kAppearance);
  EXPECT_EQ(ranked.match_id, 1);
  EXPECT_EQ(ranked.match_id, full.match_id);
  EXPECT_EQ(ranked.matches, full.matches);
  EXPECT_EQ(ranked.inliers, full.inliers);
  EXPECT_EQ(ranked.candidates, 0);  // the search area held none
  LoopDetector::Options bad;
  bad.fallback_candidates = -1;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// Raw pose resets (bad input): a vSLAM that re-initialises continues in another world
// frame. The place of keyframe 1 is seen again by the last keyframe; keyframes 10.. are in a new
// segment, flagged by the caller or noticed as a jump. The search area then holds only the new
// segment, and the earlier one is searched by appearance: the revisit is a relocalisation into it.
// Without the segment the same poses lose the revisit (jump) or find it through a search area
// built across two world frames (caller's flag off).
TEST(LoopDetector, RawPoseResetStartsASegmentSearchedByAppearance) {
  const std::vector<cv::Mat> frames = RevisitOfKeyframeOne();
  const int64_t last = static_cast<int64_t>(frames.size()) - 1;
  // x along the path, 10 units per keyframe; `jump`: keyframes >= 10 are 10,000 units away.
  std::unique_ptr<LoopDetector> kept;  // the detector of the last run
  const auto run = [&](bool jump, bool flag, double jump_factor, bool fallback = true) {
    LoopDetector::Options o = RadiusSearch(5.0);
    o.pose_jump_factor = jump_factor;
    o.appearance_fallback = fallback;
    kept = std::make_unique<LoopDetector>(o);
    LoopDetector& detector = *kept;
    std::vector<LoopResult> results;
    for (int64_t i = 0; i <= last; ++i) {
      KeyframeInput in = Input(i, frames[static_cast<size_t>(i)]);
      double x = 10.0 * static_cast<double>(i);
      if (i == last) x = 10.0;  // the revisit, where keyframe 1 was (no jump: 15 steps back)
      if (jump && i >= 10) x += 10000.0;
      in.world_from_cam = Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, 0, 0));
      in.pose_reset = flag && i == 10;
      results.push_back(detector.Process(in));
    }
    return results;
  };
  const std::vector<LoopResult> jumped = run(true, false, 20.0);
  for (int64_t i = 0; i <= last; ++i) {
    const LoopResult& r = jumped[static_cast<size_t>(i)];
    EXPECT_EQ(r.pose_segment, i >= 10 ? 1 : 0) << i;
    EXPECT_EQ(r.pose_reset, i == 10 ? PoseReset::kTranslationJump : PoseReset::kNone) << i;
  }
  const LoopResult& found = jumped.back();
  ASSERT_TRUE(found.detected()) << ToString(found.status);
  EXPECT_EQ(found.match_id, 1);
  EXPECT_EQ(found.source, CandidateSource::kEarlierSegment);
  EXPECT_TRUE(found.relocalization);
  EXPECT_EQ(found.candidates, 0);  // the new segment's area held nothing near the revisit
  EXPECT_TRUE(found.has_world_from_query);
  // Asked directly (MatchAgainst), a keyframe before the reset is a relocalisation too: no pose
  // check across the frames, and no accepted loop for the new segment's area and gate.
  const LoopResult direct = kept->MatchAgainst(kept->record(last), {1});
  ASSERT_TRUE(direct.detected()) << ToString(direct.status);
  EXPECT_EQ(direct.source, CandidateSource::kEarlierSegment);
  EXPECT_TRUE(direct.relocalization);
  // The same jump, unnoticed: the area is built across both frames and holds nothing near; only
  // the appearance fallback (default on) finds the place, as a loop in one (wrong) world frame.
  const LoopResult lost = run(true, false, 0.0, false).back();
  EXPECT_FALSE(lost.detected()) << ToString(lost.status);
  EXPECT_EQ(lost.pose_reset, PoseReset::kNone);
  const LoopResult by_appearance = run(true, false, 0.0).back();
  ASSERT_TRUE(by_appearance.detected()) << ToString(by_appearance.status);
  EXPECT_EQ(by_appearance.match_id, 1);
  EXPECT_EQ(by_appearance.source, CandidateSource::kAppearance);
  EXPECT_FALSE(by_appearance.relocalization);

  // No jump in the numbers: only the caller knows. Unflagged, the area finds keyframe 1 as a
  // loop in one world frame; flagged, the area of the new segment cannot hold it.
  const LoopResult unflagged = run(false, false, 20.0).back();
  ASSERT_TRUE(unflagged.detected()) << ToString(unflagged.status);
  EXPECT_EQ(unflagged.source, CandidateSource::kSearchArea);
  EXPECT_FALSE(unflagged.relocalization);
  const std::vector<LoopResult> flagged = run(false, true, 20.0);
  EXPECT_EQ(flagged[10].pose_reset, PoseReset::kCaller);
  ASSERT_TRUE(flagged.back().detected()) << ToString(flagged.back().status);
  EXPECT_EQ(flagged.back().match_id, 1);
  EXPECT_EQ(flagged.back().source, CandidateSource::kEarlierSegment);
  EXPECT_TRUE(flagged.back().relocalization);
  EXPECT_EQ(flagged.back().pose_segment, 1);
}

// Which raw steps count as a reset: rotation and scale steps beyond their limits, once the segment
// has 5 steps; a long step after a stop does not (the mean step, not only the median of the last
// steps, sets the usual step).
TEST(LoopDetector, PoseJumpRules) {
  const auto reasons = [](const std::vector<Sim3d>& poses) {
    LoopDetector detector(LoopDetector::Options{});
    std::vector<PoseReset> out;
    for (size_t i = 0; i < poses.size(); ++i) {
      KeyframeInput in = Input(static_cast<int64_t>(i), Textured(100 + i));
      in.world_from_cam = poses[i];
      out.push_back(detector.Process(in).pose_reset);
    }
    return out;
  };
  const auto at = [](double x, double yaw_deg = 0.0, double scale = 1.0) {
    return Sim3d(
        scale,
        Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ())),
        Eigen::Vector3d(x, 0, 0));
  };
  using R = PoseReset;
  // The rules start after 5 steps of the segment: keyframes 0-5, then the step under test.
  const auto after_five = [&](const std::vector<Sim3d>& tail) {
    std::vector<Sim3d> poses;
    for (int i = 0; i <= 5; ++i) poses.push_back(at(i));
    poses.insert(poses.end(), tail.begin(), tail.end());
    return reasons(poses);
  };
  const std::vector<R> none6(6, R::kNone);
  const auto with = [&](std::vector<R> tail) {
    std::vector<R> all = none6;
    all.insert(all.end(), tail.begin(), tail.end());
    return all;
  };
  EXPECT_EQ(after_five({at(6, 10), at(7, 120)}), with({R::kNone, R::kRotationJump}));
  EXPECT_EQ(after_five({at(6, 0, 0.4), at(7, 0, 0.5)}), with({R::kScaleJump, R::kNone}));
  // Fewer than 5 steps: a keyframe turned by 170 deg is not a reset (sparse views of one place).
  EXPECT_EQ(reasons({at(0), at(1, 170), at(2, 0, 0.1)}),
            (std::vector<R>{R::kNone, R::kNone, R::kNone}));
  // 6 steps of 1, a stop of 30 keyframes, then steps of 1 again; then a jump of 500.
  std::vector<Sim3d> stop;
  for (int i = 0; i <= 6; ++i) stop.push_back(at(i));
  for (int i = 0; i < 30; ++i) stop.push_back(at(6));
  for (int i = 7; i <= 9; ++i) stop.push_back(at(i));
  stop.push_back(at(509));
  const std::vector<R> got = reasons(stop);
  for (size_t i = 0; i + 1 < got.size(); ++i) EXPECT_EQ(got[i], R::kNone) << i;
  EXPECT_EQ(got.back(), R::kTranslationJump);
  // The flag needs a pose (the first pose in the new frame).
  LoopDetector detector(LoopDetector::Options{});
  KeyframeInput no_pose = Input(0, Textured(1));
  no_pose.pose_reset = true;
  EXPECT_THROW(detector.Process(no_pose), std::invalid_argument);
  LoopDetector::Options bad;
  bad.pose_jump_max_scale = 0.5;
  EXPECT_THROW(bad.Check(), std::invalid_argument);
}

// The image cut into 8 x 8 tiles put back in another order, none in its place: most descriptors
// match the original (the tiles' insides), the geometry does not (each tile moved on its own).
cv::Mat ShuffledTiles(const cv::Mat& image, uint64_t seed) {
  constexpr int kSide = 8, kTiles = kSide * kSide;
  const int tw = image.cols / kSide, th = image.rows / kSide;
  std::vector<int> order(kTiles);
  cv::RNG rng(seed);
  bool deranged = false;
  while (!deranged) {
    for (int i = 0; i < kTiles; ++i) order[i] = i;
    for (int i = kTiles - 1; i > 0; --i) std::swap(order[i], order[rng.uniform(0, i + 1)]);
    deranged = true;
    for (int i = 0; i < kTiles; ++i) deranged = deranged && order[i] != i;
  }
  cv::Mat out = image.clone();
  for (int i = 0; i < kTiles; ++i) {
    const cv::Rect from((order[i] % kSide) * tw, (order[i] / kSide) * th, tw, th);
    image(from).copyTo(out(cv::Rect((i % kSide) * tw, (i / kSide) * th, tw, th)));
  }
  return out;
}

// Close scores (Options::verify_close_fraction): six stored keyframes are the query's place with
// its tiles shuffled, so all six reach similar descriptor match counts and none verifies. The
// default verifies the best three; with close scores every candidate within the fraction of the
// third's count is verified too, up to max_verify_close; the counts come from the ranking.
TEST(LoopDetector, CloseScoresVerifyMoreThanMaxVerify) {
  const cv::Mat place = Textured(7);
  std::vector<cv::Mat> frames;
  for (uint64_t seed = 0; seed < 6; ++seed) frames.push_back(ShuffledTiles(place, seed + 1));
  frames.push_back(Textured(100));  // 6, 7: fillers (exclude_recent = 2)
  frames.push_back(Textured(101));
  frames.push_back(Shifted(place));  // 8: the query
  const auto run = [&](double fraction, int cap) {
    LoopDetector::Options o = RadiusSearch(100.0);
    o.verify_close_fraction = fraction;
    o.max_verify_close = cap;
    return LastResultAlongX(o, frames, 1.0);
  };
  const LoopResult plain = run(0.0, 8);
  ASSERT_FALSE(plain.detected()) << ToString(plain.status);
  EXPECT_EQ(plain.verified_in_area.size(), 3u);  // max_verify
  const LoopResult close = run(0.5, 8);
  EXPECT_FALSE(close.detected());
  EXPECT_GT(close.verified_in_area.size(), 3u);
  EXPECT_LE(close.verified_in_area.size(), 6u);  // the six shuffled ones at most
  // The first three are the same candidates in the same order; the cap holds.
  EXPECT_TRUE(std::equal(plain.verified_in_area.begin(), plain.verified_in_area.end(),
                         close.verified_in_area.begin()));
  EXPECT_EQ(run(0.5, 4).verified_in_area.size(), 4u);
  // A fraction of 1 adds only candidates with as many matches as the third (none here or ties).
  EXPECT_LE(run(1.0, 8).verified_in_area.size(), close.verified_in_area.size());
}

TEST(LoopDetector, CheckEveryNSkipsButStores) {
  LoopDetector::Options o = GlobalNoExclusion();
  o.check_every = 2;
  LoopDetector detector(o);
  const cv::Mat a = Textured(1);
  EXPECT_EQ(detector.Process(Input(0, a)).status, LoopStatus::kSkipped);
  const LoopResult second = detector.Process(Input(1, Shifted(a)));  // checked: matches 0
  EXPECT_TRUE(second.detected()) << ToString(second.status);
  EXPECT_EQ(detector.Process(Input(2, a)).status, LoopStatus::kSkipped);
  EXPECT_EQ(detector.num_keyframes(), 3u);
}

TEST(LoopDetector, ConsistencyRejectsRotationDisagreeingWithPrior) {
  LoopDetector::Options o = GlobalNoExclusion();
  LoopDetector detector(o);
  const cv::Mat a = Textured(1);
  KeyframeInput first = Input(0, a);
  first.world_from_cam = Sim3d();
  detector.Process(first);
  // Same image (relative rotation ~0), but the prior claims a 90 deg turn.
  KeyframeInput second = Input(1, Shifted(a));
  second.world_from_cam =
      Sim3d(1.0, ExpSO3(Eigen::Vector3d(0, M_PI / 2, 0)), Eigen::Vector3d(10, 0, 0));
  const LoopResult r = detector.Process(second);
  EXPECT_EQ(r.status, LoopStatus::kRejectedByConsistency);
  EXPECT_NEAR(r.rotation_error_vs_prior_deg, 90.0, 2.0);
}

TEST(LoopDetector, Deterministic) {
  auto run = [] {
    LoopDetector detector(GlobalNoExclusion());
    std::vector<LoopResult> out;
    for (int i = 0; i < 4; ++i) out.push_back(detector.Process(Input(i, Textured(1 + i % 2))));
    return out;
  };
  const auto a = run(), b = run();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].status, b[i].status);
    EXPECT_EQ(a[i].match_id, b[i].match_id);
    EXPECT_EQ(a[i].inliers, b[i].inliers);
    EXPECT_EQ(a[i].match_from_query.rotation.coeffs(), b[i].match_from_query.rotation.coeffs());
  }
}

}  // namespace
}  // namespace sparseloop
