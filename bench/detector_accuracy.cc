// Detector accuracy on the real data, as ONE JSON object on stdout (collected into
// docs/BENCHMARKS.md by scripts/benchmark). Not a Google Benchmark: it measures accuracy, not time.
//   build/bin/detector_accuracy [--data DIR] [--quick]
// DIR defaults to $SPARSELOOP_DATA, else the configured SPARSELOOP_DATA_DIR (../shared/data).
// Exit 0 on success, 2 when the data (or an argument) is missing. Runtime ~1-2 min on one core.
//
// What it prints (docs/DETECTOR.md explains every number):
//   rtabmap[ranking][K]: detections, true positives, precision, recall, recall@100%P
//     (rtabmap_corridor_loop, global search, no poses, guessed intrinsics, default options but K,
//     ranking popcount / response / grid, K in {8,10,12,15,18,32,50,64,100,300});
//   rtabmap.oracle[symmetric_K | asymmetric_K]: every pair verified, per query the best true and
//     false pair's inliers, the best recall@100%P of any inlier threshold and the best recall
//     with at most one false loop and with the weak-pair agreement rule (RtabmapOracle below;
//     K 15, 20, 300 and asymmetric 16-18);
//   castle: the default detector over views 0001..0029 with GT poses: loops found, the 29 -> x
//     loop's relative rotation error and translation direction error vs GT, degrees;
//   castle_pairs[ranking][K]: descriptor matches and essential inliers (min_inliers 5) of the
//     true loops 29-01, 29-02 and the false pairs 29-15, 20-05, K in {15, 50};
//   euroc: both loop pairs, default options (global search), monocular and with stereo depths:
//   status, method, inliers, rotation / direction (and metric translation) error;
//   euroc_pairs_by_k[ranking][K]: matches and essential inliers of the true pairs 1-0, 3-2 and
//     the false pairs 2-0, 3-1, K in {15, 50, 100, 200, 300}.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "castle_input.h"
#include "euroc_pairs.h"
#include "program_main.h"
#include "real_data.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/matching/descriptor_matching.h"
#include "sparseloop/matching/geometric_verification.h"

namespace sparseloop {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

double Deg(double rad) { return rad * 180.0 / M_PI; }
double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Deg(std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)));
}

// ---- castle_p30_768: views 0001..0029 with their exact poses (tests/support/real_data.h).
using test::Frame;

json CastleLoop(const std::vector<Frame>& frames) {
  LoopDetector detector(LoopDetector::Options{});
  json loops = json::array();
  json out;
  for (size_t i = 0; i < frames.size(); ++i) {
    const KeyframeInput in = test::CastleKeyframe(frames, i);
    const LoopResult r = detector.Process(in);
    if (!r.detected()) continue;
    const Rigid3d gt = frames[r.match_id - 1].world_from_cam.Inverse() * frames[i].world_from_cam;
    loops.push_back(
        {{"query", r.query_id},
         {"match", r.match_id},
         {"inliers", r.inliers},
         {"rotation_error_deg", Deg(RotationAngle(gt.rotation, r.match_from_query.rotation))},
         {"translation_direction_error_deg",
          AngleBetween(gt.translation, r.match_from_query.translation)}});
  }
  out["loops"] = loops;
  out["ring_closure_found"] = loops.size() == 1 && loops[0]["query"] == 29 &&
                              (loops[0]["match"] == 1 || loops[0]["match"] == 2);
  return out;
}

KeyframeRecord Extract(const Frame& f, const FeatureOptions& o) {
  KeyframeRecord r;
  FeatureInput in;
  in.image = &f.image;
  in.intrinsics = &f.intrinsics;
  ExtractInformativeFeatures(in, o, &r);
  return r;
}

json CastlePairs(const std::vector<Frame>& frames) {
  const std::vector<std::pair<int, int>> pairs = {{29, 1}, {29, 2}, {29, 15}, {20, 5}};
  json out;
  for (auto ranking :
       {FeatureRanking::kPopcount, FeatureRanking::kResponse, FeatureRanking::kGridResponse}) {
    for (int k : {15, 50}) {
      FeatureOptions fo;
      fo.ranking = ranking;
      fo.max_features = k;
      json row;
      for (auto [q, m] : pairs) {
        const KeyframeRecord rq = Extract(frames[q - 1], fo);
        const KeyframeRecord rm = Extract(frames[m - 1], fo);
        const auto matches = MatchDescriptors(rq.descriptors, rm.descriptors, MatchOptions{});
        VerifyOptions vo;
        vo.min_inliers = 5;
        const auto v = VerifyPair(rq, rm, matches, vo);
        char key[16];
        std::snprintf(key, sizeof(key), "%02d-%02d", q, m);
        row[key] = {{"matches", static_cast<int>(matches.size())},
                    {"inliers", v.inliers},
                    {"true_loop", q == 29 && (m == 1 || m == 2)}};
      }
      out[ToString(ranking)][std::to_string(k)] = row;
    }
  }
  return out;
}

// ---- euroc_loop_pairs by K: descriptor matches and essential inliers (min_inliers 5) of the two
// true pairs (1-0, 3-2) and two false ones (2-0, 3-1), left images, response / grid ranking.
json EurocPairsByK(const fs::path& root) {
  Frame f[4];
  for (int i = 0; i < 4; ++i) {
    f[i].image = test::EurocImage(root, "left", i);
    f[i].intrinsics = test::EurocIntrinsics(0);
  }
  json out;
  for (auto ranking : {FeatureRanking::kResponse, FeatureRanking::kGridResponse}) {
    for (int k : {15, 50, 100, 200, 300}) {
      FeatureOptions fo;
      fo.ranking = ranking;
      fo.max_features = k;
      json row;
      for (auto [q, m] : std::vector<std::pair<int, int>>{{1, 0}, {3, 2}, {2, 0}, {3, 1}}) {
        const KeyframeRecord rq = Extract(f[q], fo);
        const KeyframeRecord rm = Extract(f[m], fo);
        const auto matches = MatchDescriptors(rq.descriptors, rm.descriptors, MatchOptions{});
        VerifyOptions vo;
        vo.min_inliers = 5;
        const auto v = VerifyPair(rq, rm, matches, vo);
        row[std::to_string(q) + "-" + std::to_string(m)] = {
            {"matches", static_cast<int>(matches.size())},
            {"inliers", v.inliers},
            {"true_loop", q - m == 1}};
      }
      out[ToString(ranking)][std::to_string(k)] = row;
    }
  }
  return out;
}

json RtabmapOracle(const std::vector<cv::Mat>& images, const std::set<std::pair<int, int>>& gt,
                   const std::set<int>& queries_with_gt);

// ---- rtabmap_corridor_loop: no poses, guessed intrinsics, GT loop pairs (1-based in the file).
json Rtabmap(const fs::path& root, bool quick) {
  std::vector<cv::Mat> images;
  for (int i = 1; i <= 84; ++i) {
    images.push_back(cv::imread((root / "samples" / (std::to_string(i) + ".jpg")).string(),
                                cv::IMREAD_GRAYSCALE));
    if (images.back().empty())
      throw std::runtime_error("cannot read rtabmap image " + std::to_string(i));
  }
  std::set<std::pair<int, int>> gt;
  std::set<int> queries_with_gt;
  {
    std::ifstream in(root / "gt_loops_from_bmp.txt");
    std::string line;
    while (std::getline(in, line)) {
      int q, m;
      if (line.empty() || line[0] == '#') continue;
      if (std::sscanf(line.c_str(), "%d %d", &q, &m) == 2) {
        gt.insert({q - 1, m - 1});
        queries_with_gt.insert(q - 1);
      }
    }
  }
  const std::vector<int> ks =
      quick ? std::vector<int>{15, 50} : std::vector<int>{8, 10, 12, 15, 18, 32, 50, 64, 100, 300};
  json out;
  out["queries_with_gt"] = static_cast<int>(queries_with_gt.size());
  out["oracle"] = RtabmapOracle(images, gt, queries_with_gt);
  for (auto ranking :
       {FeatureRanking::kPopcount, FeatureRanking::kResponse, FeatureRanking::kGridResponse}) {
    for (int k : ks) {
      LoopDetector::Options options;
      options.features.max_features = k;
      options.features.ranking = ranking;
      options.search.strategy = SearchStrategy::kGlobal;
      LoopDetector detector(options);
      std::vector<std::pair<double, bool>> scored;
      int detections = 0, tp = 0;
      for (size_t i = 0; i < images.size(); ++i) {
        KeyframeInput in;
        in.id = static_cast<int64_t>(i);
        in.timestamp = static_cast<double>(i);
        in.image = images[i];
        in.intrinsics = test::GuessIntrinsics(images[i].cols, images[i].rows);
        const LoopResult r = detector.Process(in);
        if (!r.detected()) continue;
        const bool ok = gt.count({static_cast<int>(r.query_id), static_cast<int>(r.match_id)}) > 0;
        ++detections;
        tp += ok;
        scored.emplace_back(r.score, ok);
      }
      std::stable_sort(scored.begin(), scored.end(),
                       [](const auto& a, const auto& b) { return a.first > b.first; });
      double recall_full = 0;
      int run = 0;
      for (size_t i = 0; i < scored.size(); ++i) {
        if (!scored[i].second) break;
        ++run;
        if (i + 1 == scored.size() || scored[i + 1].first != scored[i].first)
          recall_full = double(run) / queries_with_gt.size();
      }
      out[ToString(ranking)][std::to_string(k)] = {
          {"detections", detections},
          {"true_positives", tp},
          {"precision", detections ? double(tp) / detections : 1.0},
          {"recall", double(tp) / queries_with_gt.size()},
          {"recall_at_full_precision", recall_full}};
    }
  }
  return out;
}

// A query's top pair in the oracle: its inliers, match and truth.
struct OracleTop {
  int inliers = 0;
  int match = -1;
  bool true_pair = false;
};

// The best recall@100%P of the weak-pair rule (LoopDetector::Options::weak_pairs) on the
// oracle's top pairs: a top pair is accepted at >= strong inliers, or at >= weak when the last
// accepted query is at most `window` keyframes back and its match at most window + that gap
// from this one (LoopDetector::Agrees). Over strong in [5, 30], weak in [5, strong]; an upper
// bound for a detector that agrees consecutive queries this way and ranks by inliers.
json AgreementCeiling(const std::vector<OracleTop>& top, size_t queries_with_gt, int window) {
  double best = 0.0;
  int best_strong = 0, best_weak = 0;
  for (int strong = 5; strong <= 30; ++strong) {
    for (int weak = 5; weak <= strong; ++weak) {
      int tp = 0, fp = 0, last_q = -1, last_m = -1;
      for (int q = 0; q < static_cast<int>(top.size()) && fp == 0; ++q) {
        const OracleTop& t = top[static_cast<size_t>(q)];
        if (t.inliers < weak) continue;
        const bool agrees = last_q >= 0 && q - last_q <= window &&
                            std::abs(t.match - last_m) <= window + (q - last_q);
        if (t.inliers < strong && !agrees) continue;
        (t.true_pair ? tp : fp) += 1;
        last_q = q;
        last_m = t.match;
      }
      const double recall = double(tp) / double(queries_with_gt);
      if (fp == 0 && recall > best) {
        best = recall;
        best_strong = strong;
        best_weak = weak;
      }
    }
  }
  return {{"recall", best}, {"strong", best_strong}, {"weak", best_weak}};
}

// ---- rtabmap oracle: what single-pair verification can reach at a given K, whatever the
// search. Every pair at least `exclude_recent` (30) apart is matched and verified (5-inlier floor
// so that counts below the detector's floors are seen); per query the best GT-true and the best
// false pair. A detector that verifies every pair and accepts the top pair at >= t inliers
// recalls the GT queries whose best true pair has >= t inliers and beats every false one; its
// precision is 1 only while no query's top pair is a false one with >= t. `ceiling` is the best
// recall@100%P over t in [5, 60]; `verifiable_at_8` the GT queries whose best true pair reaches
// the small-K floor of 8 (docs/DETECTOR.md "Small K").
json RtabmapOracle(const std::vector<cv::Mat>& images, const std::set<std::pair<int, int>>& gt,
                   const std::set<int>& queries_with_gt) {
  json out;
  const int gap = 30;  // recent keyframes that are no GT revisit (the paper area's own gap)
  for (const int k : {15, 16, 17, 18, 20, 300}) {
    for (const bool asymmetric : {false, true}) {
      if (k == 300 && asymmetric) continue;  // the query extraction is K already
      if (k != 15 && k != 20 && k != 300 && !asymmetric) continue;  // K 16-18: the byte limit
      LoopDetector::Options options;
      FeatureOptions stored_options = options.features;
      stored_options.max_features = k;
      FeatureOptions query_options = stored_options;
      if (asymmetric) query_options.max_features = options.query_max_features;
      std::vector<KeyframeRecord> stored(images.size()), query(images.size());
      for (size_t i = 0; i < images.size(); ++i) {
        const CameraIntrinsics intr = test::GuessIntrinsics(images[i].cols, images[i].rows);
        FeatureInput in;
        in.image = &images[i];
        in.intrinsics = &intr;
        ExtractInformativeFeatures(in, stored_options, &stored[i]);
        ExtractInformativeFeatures(in, query_options, &query[i]);
      }
      VerifyOptions verify = options.verify;
      verify.min_inliers = 5;
      const int n = static_cast<int>(images.size());
      std::vector<int> best_true(images.size(), 0), best_false(images.size(), 0);
      std::vector<int> true_match(images.size(), -1), false_match(images.size(), -1);
      for (int q = 0; q < n; ++q) {
        for (int m = 0; m + gap < q; ++m) {
          const std::vector<DescriptorMatch> matches =
              asymmetric
                  ? MatchStoredIntoQuery(query[q].descriptors, stored[m].descriptors, options.match)
                  : MatchDescriptors(query[q].descriptors, stored[m].descriptors, options.match);
          if (matches.size() < 5) continue;
          const VerificationResult v = VerifyPair(query[q], stored[m], matches, verify);
          const int inliers = v.success ? v.inliers : 0;
          const bool is_true = gt.count({q, m}) > 0;
          int& best = is_true ? best_true[q] : best_false[q];
          if (inliers > best) {
            best = inliers;
            (is_true ? true_match[q] : false_match[q]) = m;
          }
        }
      }
      double ceiling = 0.0, ceiling_one_false = 0.0;
      int ceiling_t = 0;
      json by_threshold = json::array();
      for (int t = 5; t <= 60; ++t) {
        int tp = 0, fp = 0;
        for (int q = 0; q < n; ++q) {
          const bool true_on_top = best_true[q] > best_false[q];
          if (true_on_top && best_true[q] >= t && queries_with_gt.count(q)) ++tp;
          if (!true_on_top && best_false[q] >= t) ++fp;
        }
        const double recall = double(tp) / double(queries_with_gt.size());
        if (t <= 16) by_threshold.push_back({{"t", t}, {"recall", recall}, {"false", fp}});
        if (fp == 0 && recall > ceiling) {
          ceiling = recall;
          ceiling_t = t;
        }
        if (fp <= 1) ceiling_one_false = std::max(ceiling_one_false, recall);
      }
      int verifiable = 0;
      json true_counts = json::array(), false_counts = json::array();
      for (int q : queries_with_gt) {
        verifiable += best_true[static_cast<size_t>(q)] >= 8;
        true_counts.push_back(best_true[static_cast<size_t>(q)]);
      }
      for (int q = 0; q < n; ++q) false_counts.push_back(best_false[static_cast<size_t>(q)]);
      std::vector<OracleTop> top(images.size());
      for (size_t q = 0; q < images.size(); ++q) {
        const bool true_on_top = best_true[q] > best_false[q];
        top[q] = {true_on_top ? best_true[q] : best_false[q],
                  true_on_top ? true_match[q] : false_match[q], true_on_top};
      }
      out[(asymmetric ? "asymmetric_" : "symmetric_") + std::to_string(k)] = {
          {"ceiling", ceiling},
          {"ceiling_threshold", ceiling_t},
          {"ceiling_one_false", ceiling_one_false},
          {"ceiling_with_agreement",
           AgreementCeiling(top, queries_with_gt.size(), options.agreement_window)},
          {"by_threshold", by_threshold},
          {"verifiable_at_8", double(verifiable) / double(queries_with_gt.size())},
          {"best_true_inliers", true_counts},
          {"best_false_inliers", false_counts}};
    }
  }
  return out;
}

// ---- euroc_loop_pairs (tests/support/euroc_pairs.h): monocular, and with the stereo-mapped
// depths.
json Euroc(const fs::path& root) {
  json out = json::array();
  for (const bool stereo : {false, true}) {
    for (int pair = 0; pair < 2; ++pair) {
      const test::EurocPairResult r = test::RunEurocPair(root, pair, stereo);
      json row = {{"pair", {2 * pair, 2 * pair + 1}},
                  {"depths", stereo ? "stereo" : "none"},
                  {"status", ToString(r.result.status)},
                  {"method", ToString(r.result.method)},
                  {"inliers", r.result.inliers},
                  {"matches", r.result.matches},
                  {"planar_alternative", r.result.planar_alternative},
                  {"rotation_error_deg", r.rotation_error_deg},
                  {"translation_direction_error_deg", r.translation_direction_error_deg}};
      if (r.translation_error_m >= 0) row["translation_error_m"] = r.translation_error_m;
      out.push_back(row);
    }
  }
  return out;
}

int Main(int argc, char** argv) {
  fs::path data = test::DataDir();
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--data" && i + 1 < argc) {
      data = argv[++i];
    } else if (a == "--quick") {
      quick = true;
    } else if (a == "--help" || a == "-h") {
      std::printf("usage: detector_accuracy [--data DIR] [--quick]\n");
      return 0;
    } else {
      std::fprintf(stderr, "detector_accuracy: unknown argument '%s' (try --help)\n", a.c_str());
      return 2;
    }
  }
  for (const char* d : {"castle_p30_768", "rtabmap_corridor_loop", "euroc_loop_pairs"}) {
    if (!fs::exists(data / d)) {
      std::fprintf(stderr,
                   "detector_accuracy: real data not found: %s (pass --data DIR or set "
                   "SPARSELOOP_DATA to the shared data folder)\n",
                   (data / d).string().c_str());
      return 2;
    }
  }
  cv::setNumThreads(1);
  json out;
  out["data"] = data.string();
  const auto castle = test::LoadCastle(/*transpose=*/false, data / "castle_p30_768");
  out["castle"] = CastleLoop(castle);
  out["castle_pairs"] = CastlePairs(castle);
  out["euroc"] = Euroc(data / "euroc_loop_pairs");
  out["euroc_pairs_by_k"] = EurocPairsByK(data / "euroc_loop_pairs");
  out["rtabmap"] = Rtabmap(data / "rtabmap_corridor_loop", quick);
  std::cout << out.dump(1) << "\n";
  return 0;
}

}  // namespace
}  // namespace sparseloop

int main(int argc, char** argv) {
  return sparseloop::test::RunProgram("detector_accuracy", 1,
                                      [&] { return sparseloop::Main(argc, argv); });
}
