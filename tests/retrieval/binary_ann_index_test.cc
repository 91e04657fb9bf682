// BinaryAnnIndex (FAISS binary HNSW) against brute-force Hamming kNN, keyframe votes on synthetic
// images, and LoopDetector's `retrieval = ann` against brute-force candidate matching.
#include "sparseloop/retrieval/binary_ann_index.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <random>
#include <set>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "cameras.h"
#include "sparseloop/loop/loop_detector.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// Lower bounds on recall, each a measurement (FAISS 1.7.3 bookworm, hnsw_m 16, ef_construction
// 40, 20k stored) minus a margin for another BLAS / FAISS build.
// Uniform random (tie-aware): recall@1 0.163 (ef 16), 0.663 (ef 128); recall@5 0.352 (ef 128).
constexpr double kUniformRecallEf16 = 0.12;
constexpr double kUniformRecallEf128 = 0.60;
constexpr double kUniformRecall5Ef128 = 0.30;
// Planted neighbour (8..24 bits away) recall@1: 0.908 (ef 32), 0.980 (ef 64, the default),
// 0.998 (ef 128).
double PlantedBound(int ef_search) {
  return ef_search <= 32 ? 0.87 : ef_search <= 64 ? 0.96 : 0.99;
}

Descriptor RandomDescriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

Descriptor FlipBits(Descriptor d, int bits, std::mt19937_64& rng) {
  std::vector<int> positions(256);
  for (int i = 0; i < 256; ++i) positions[i] = i;
  std::shuffle(positions.begin(), positions.end(), rng);
  for (int i = 0; i < bits; ++i) d[positions[i] / 64] ^= uint64_t{1} << (positions[i] % 64);
  return d;
}

// `keyframes` keyframes of `per_keyframe` random descriptors; returns them flattened.
std::vector<Descriptor> FillIndex(BinaryAnnIndex* index, int keyframes, int per_keyframe,
                                  std::mt19937_64& rng) {
  std::vector<Descriptor> all;
  for (int k = 0; k < keyframes; ++k) {
    std::vector<Descriptor> d(per_keyframe);
    for (auto& x : d) x = RandomDescriptor(rng);
    index->Add(k, d);
    all.insert(all.end(), d.begin(), d.end());
  }
  return all;
}

// Tie-aware recall@k: fraction of the exact k nearest distances matched by the ANN's k nearest
// (sorted distances compared position by position, so equally distant neighbours count alike).
double RecallAtK(const BinaryAnnIndex& index, const std::vector<Descriptor>& stored,
                 const std::vector<Descriptor>& queries, int k) {
  std::vector<std::vector<int>> exact_d;
  BruteForceKnn(queries, stored, k, &exact_d);
  const auto ann = index.Search(queries, k);
  int hit = 0, total = 0;
  for (size_t q = 0; q < queries.size(); ++q) {
    for (int j = 0; j < k; ++j) {
      ++total;
      if (j < static_cast<int>(ann[q].size()) && ann[q][j].distance <= exact_d[q][j]) ++hit;
    }
  }
  return double(hit) / total;
}

TEST(BinaryAnnIndex, OptionsCheck) {
  EXPECT_NO_THROW(BinaryAnnOptions{}.Check());
  auto bad = [](auto mutate) {
    BinaryAnnOptions o;
    mutate(o);
    EXPECT_THROW(o.Check(), std::invalid_argument);
    EXPECT_THROW(BinaryAnnIndex{o}, std::invalid_argument);
  };
  bad([](BinaryAnnOptions& o) { o.hnsw_m = 1; });
  bad([](BinaryAnnOptions& o) { o.ef_construction = 0; });
  bad([](BinaryAnnOptions& o) { o.neighbors = 0; });
  bad([](BinaryAnnOptions& o) { o.ef_search = 1, o.neighbors = 2; });
  bad([](BinaryAnnOptions& o) { o.max_distance = 257; });
  bad([](BinaryAnnOptions& o) { o.max_candidates = 0; });
  bad([](BinaryAnnOptions& o) { o.num_threads = 0; });
}

TEST(BinaryAnnIndex, EmptyIndexAndIdOrder) {
  BinaryAnnIndex index;
  std::mt19937_64 rng = test::SeededRng();
  const std::vector<Descriptor> q = {RandomDescriptor(rng)};
  EXPECT_TRUE(index.Search(q, 3)[0].empty());
  EXPECT_TRUE(index.Query(q).empty());
  index.Add(5, std::vector<Descriptor>{RandomDescriptor(rng)});
  index.Add(6, {});  // a keyframe without features is allowed
  EXPECT_THROW(index.Add(6, q), std::invalid_argument);
  EXPECT_THROW(index.Add(2, q), std::invalid_argument);
  EXPECT_THROW(index.Search(q, 0), std::invalid_argument);
  EXPECT_EQ(index.num_keyframes(), 2u);
  EXPECT_EQ(index.num_descriptors(), 1u);
  // Fewer stored than k: every stored descriptor, once.
  const auto r = index.Search(q, 4);
  ASSERT_EQ(r[0].size(), 1u);
  EXPECT_EQ(r[0][0].keyframe_id, 5);
  EXPECT_EQ(r[0][0].descriptor, 0);
}

// Every returned neighbour maps back to the right keyframe and descriptor (the label table), and
// the reported distance is the true Hamming distance.
TEST(BinaryAnnIndex, NeighboursMapToTheirKeyframeAndDistance) {
  std::mt19937_64 rng = test::SeededRng(1);
  BinaryAnnIndex index;
  std::vector<std::vector<Descriptor>> per_kf;
  for (int k = 0; k < 50; ++k) {
    std::vector<Descriptor> d(10 + k % 7);
    for (auto& x : d) x = RandomDescriptor(rng);
    index.Add(100 + 3 * k, d);
    per_kf.push_back(d);
  }
  std::vector<Descriptor> queries(200);
  for (auto& q : queries) q = RandomDescriptor(rng);
  const auto res = index.Search(queries, 5);
  for (size_t q = 0; q < queries.size(); ++q) {
    ASSERT_EQ(res[q].size(), 5u);
    for (size_t j = 0; j < res[q].size(); ++j) {  // NOLINT
      const auto& n = res[q][j];
      ASSERT_EQ((n.keyframe_id - 100) % 3, 0);
      const auto& kf = per_kf[static_cast<size_t>((n.keyframe_id - 100) / 3)];
      ASSERT_LT(n.descriptor, static_cast<int>(kf.size()));
      EXPECT_EQ(n.distance, HammingDistance(queries[q], kf[n.descriptor]));
      if (j > 0) {
        EXPECT_LE(res[q][j - 1].distance, n.distance);
      }
    }
  }
}

// Loop-closure case: the query descriptor is a noisy copy (8..24 bits flipped) of a stored one,
// every other stored descriptor is ~128 bits away; the brute-force oracle finds the planted one.
// Recall@1 by ef_search: see PlantedBound (20k stored, 500 queries).
TEST(BinaryAnnIndex, FindsPlantedNeighboursLikeBruteForce) {
  for (int ef : {32, 64, 128}) {
    std::mt19937_64 rng = test::SeededRng(2);
    BinaryAnnOptions o;
    o.ef_search = ef;
    BinaryAnnIndex index(o);
    const auto stored = FillIndex(&index, 200, 100, rng);
    std::vector<Descriptor> queries;
    std::vector<int> truth;
    std::uniform_int_distribution<int> pick(0, static_cast<int>(stored.size()) - 1), bits(8, 24);
    for (int i = 0; i < 500; ++i) {
      truth.push_back(pick(rng));
      queries.push_back(FlipBits(stored[truth.back()], bits(rng), rng));
    }
    const auto exact = BruteForceKnn(queries, stored, 1);
    const auto ann = index.Search(queries, 1);
    int found = 0;
    for (size_t q = 0; q < queries.size(); ++q) {
      ASSERT_EQ(exact[q][0], truth[q]);  // the oracle agrees with the construction
      const int label = static_cast<int>(ann[q][0].keyframe_id * 100 + ann[q][0].descriptor);
      found += label == truth[q];
    }
    const double recall = double(found) / queries.size();
    std::printf("planted, 20k stored: ef_search %d recall@1 %.3f\n", ef, recall);
    EXPECT_GE(recall, PlantedBound(ef)) << ef;
  }
}

// Worst case for any ANN: uniform random queries (no structure, all distances ~ 70..128 bits).
// Measured tie-aware recall@1 / recall@5 with 20k stored, 300 queries: see the printed values;
// the bounds sit below the measurement. A larger ef_search must not lower recall.
TEST(BinaryAnnIndex, RecallOnUniformRandomAgainstBruteForce) {
  std::mt19937_64 rng = test::SeededRng(3);
  BinaryAnnOptions low, high;
  low.ef_search = 16;
  high.ef_search = 128;
  BinaryAnnIndex a(low), b(high);
  std::mt19937_64 rng_b = rng;
  const auto stored = FillIndex(&a, 200, 100, rng);
  FillIndex(&b, 200, 100, rng_b);
  std::vector<Descriptor> queries(300);
  for (auto& q : queries) q = RandomDescriptor(rng);
  const double r1_low = RecallAtK(a, stored, queries, 1);
  const double r1_high = RecallAtK(b, stored, queries, 1);
  const double r5_high = RecallAtK(b, stored, queries, 5);
  std::printf("uniform random, 20k stored: recall@1 ef16 %.3f ef128 %.3f, recall@5 ef128 %.3f\n",
              r1_low, r1_high, r5_high);
  EXPECT_GE(r1_high, r1_low);
  EXPECT_GE(r1_low, kUniformRecallEf16);
  EXPECT_GE(r1_high, kUniformRecallEf128);
  EXPECT_GE(r5_high, kUniformRecall5Ef128);
}

TEST(BinaryAnnIndex, DeterministicAndVotesCountDistinctKeyframes) {
  std::mt19937_64 rng = test::SeededRng(4);
  BinaryAnnIndex a, b;
  std::mt19937_64 rng_b = rng;
  const auto stored = FillIndex(&a, 100, 50, rng);
  FillIndex(&b, 100, 50, rng_b);
  std::vector<Descriptor> queries;
  for (int i = 0; i < 200; ++i) queries.push_back(FlipBits(stored[i * 7], 10, rng));
  const auto ra = a.Search(queries, 4), rb = b.Search(queries, 4);
  for (size_t q = 0; q < queries.size(); ++q) {
    ASSERT_EQ(ra[q].size(), rb[q].size());
    for (size_t j = 0; j < ra[q].size(); ++j) {
      EXPECT_EQ(ra[q][j].keyframe_id, rb[q][j].keyframe_id);
      EXPECT_EQ(ra[q][j].descriptor, rb[q][j].descriptor);
    }
  }
  // Votes recomputed from the exact neighbours (neighbors = 2, max_distance = 64).
  const auto votes = a.Query(queries);
  std::map<int64_t, int> expected;
  const auto exact = BruteForceKnn(queries, stored, 2);
  std::vector<std::vector<int>> exact_d;
  BruteForceKnn(queries, stored, 2, &exact_d);
  for (size_t q = 0; q < queries.size(); ++q) {
    std::set<int64_t> kfs;
    for (size_t j = 0; j < exact[q].size(); ++j)
      if (exact_d[q][j] <= 64) kfs.insert(exact[q][j] / 50);
    for (int64_t k : kfs) ++expected[k];
  }
  int total = 0;
  for (size_t i = 0; i < votes.size(); ++i) {
    total += votes[i].votes;
    if (i > 0) {
      EXPECT_GE(votes[i - 1].votes, votes[i].votes);
    }
    EXPECT_EQ(votes[i].votes, expected[votes[i].keyframe_id]) << votes[i].keyframe_id;
  }
  EXPECT_EQ(total, 200);  // each planted query: exactly one neighbour within 64 bits
}

// Memory: 32 B code + 2 * hnsw_m int32 bottom-level links + upper levels (~1/hnsw_m of the nodes)
// + level (4 B) and offset (8 B) tables = ~176 B, plus vector capacity slack (growth by doubling):
// measured 265 B per descriptor at 20k.
TEST(BinaryAnnIndex, BytesPerDescriptor) {
  std::mt19937_64 rng = test::SeededRng(5);
  BinaryAnnIndex index;
  FillIndex(&index, 100, 200, rng);
  const double per = double(index.Bytes()) / index.num_descriptors();
  std::printf("bytes per descriptor (hnsw_m 16): %.1f\n", per);
  EXPECT_GE(per, 32 + 2 * 16 * 4 + 12);
  EXPECT_LE(per, 2 * (32 + 2 * 16 * 4 + 12 + 16));
}

// ---- Synthetic images: votes find the revisited keyframe. ----
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

cv::Mat Moved(const cv::Mat& a, double angle_deg, double dx, double dy) {
  cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(160, 120), angle_deg, 1.0);
  m.at<double>(0, 2) += dx;
  m.at<double>(1, 2) += dy;
  cv::Mat out;
  cv::warpAffine(a, out, m, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  return out;
}

CameraIntrinsics Camera() { return test::SmallCamera(); }

std::vector<Descriptor> Orb1000(const cv::Mat& image) {
  FeatureOptions o;
  o.max_features = 1000;
  o.use_gradient_mask = false;
  const CameraIntrinsics cam = Camera();
  FeatureInput in;
  in.image = &image;
  in.intrinsics = &cam;
  KeyframeRecord r;
  ExtractInformativeFeatures(in, o, &r);
  return r.descriptors;
}

TEST(BinaryAnnIndex, VotesFindTheRevisitedImage) {
  BinaryAnnIndex index;
  for (int k = 0; k < 12; ++k) index.Add(k, Orb1000(Textured(100 + k)));
  for (int target : {0, 5, 11}) {
    const auto votes = index.Query(Orb1000(Moved(Textured(100 + target), 4.0, 7, -5)));
    ASSERT_GE(votes.size(), 2u);
    EXPECT_EQ(votes[0].keyframe_id, target);
    EXPECT_GT(votes[0].votes, 3 * votes[1].votes) << votes[0].votes << " vs " << votes[1].votes;
  }
}

// ---- LoopDetector: retrieval = ann gives the same loop as brute force. ----
KeyframeInput Input(int64_t id, const cv::Mat& image) {
  KeyframeInput in;
  in.id = id;
  in.timestamp = static_cast<double>(id);
  in.image = image;
  in.intrinsics = Camera();
  return in;
}

LoopDetector::Options FullGlobal(CandidateRetrieval retrieval) {
  LoopDetector::Options o;
  o.features.max_features = 1000;
  o.features.use_gradient_mask = false;
  o.search.strategy = SearchStrategy::kGlobal;
  o.search.exclude_recent = 3;
  o.min_path_ratio = 0;
  o.overlap_gap = 0;  // exclude_recent alone decides what is recent here
  o.check_consistency = false;
  o.retrieval = retrieval;
  o.ann.max_candidates = 2;
  return o;
}

TEST(LoopDetectorAnn, SameLoopAsBruteForceAndRecentKeyframesExcluded) {
  // Keyframes 0..9 distinct places; 10 revisits 2; 11 is a copy of 10's place again but 10 is
  // too recent (exclude_recent 3), so it must match 2 again, never 10.
  std::vector<cv::Mat> images;
  for (int k = 0; k < 10; ++k) images.push_back(Textured(200 + k));
  images.push_back(Moved(images[2], 3.0, 8, -4));
  images.push_back(Moved(images[2], -2.0, -6, 5));
  for (CandidateRetrieval r : {CandidateRetrieval::kBruteForce, CandidateRetrieval::kAnn}) {
    LoopDetector detector(FullGlobal(r));
    std::vector<LoopResult> results;
    for (int k = 0; k < static_cast<int>(images.size()); ++k)
      results.push_back(detector.Process(Input(k, images[k])));
    for (int k = 0; k < 10; ++k) EXPECT_FALSE(results[k].detected()) << ToString(r) << " " << k;
    for (int k : {10, 11}) {
      EXPECT_TRUE(results[k].detected()) << ToString(r) << " " << k;
      EXPECT_EQ(results[k].match_id, 2) << ToString(r) << " " << k;
    }
    if (r == CandidateRetrieval::kAnn) {
      EXPECT_LE(results[11].candidates, 2);  // only the top-voted go to matching
      EXPECT_GT(detector.RetrievalIndexBytes(), 0u);
    } else {
      EXPECT_EQ(results[11].candidates, 8);  // 0..7: 8, 9, 10 are too recent
      EXPECT_EQ(detector.RetrievalIndexBytes(), 0u);
    }
  }
}

TEST(LoopDetectorAnn, RetrievalNamesAndOptions) {
  EXPECT_EQ(ParseCandidateRetrieval("ann"), CandidateRetrieval::kAnn);
  EXPECT_EQ(ParseCandidateRetrieval("brute_force"), CandidateRetrieval::kBruteForce);
  EXPECT_STREQ(ToString(CandidateRetrieval::kAnn), "ann");
  EXPECT_THROW(ParseCandidateRetrieval("hnsw"), std::invalid_argument);
  LoopDetector::Options o;
  o.ann.neighbors = 0;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  EXPECT_THROW(LoopDetector{o}, std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop
