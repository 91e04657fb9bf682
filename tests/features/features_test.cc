#include <cmath>
#include <cstdio>
#include <random>
#include <set>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cameras.h"
#include "sparseloop/features/informative_features.h"
#include "sparseloop/synthetic/worlds.h"
#include "test_util.h"

namespace sparseloop {
namespace {

Descriptor RandomDescriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

TEST(Features, HammingAndPopcountKnownAnswers) {
  const Descriptor zero{0, 0, 0, 0};
  const Descriptor ones{~0ull, ~0ull, ~0ull, ~0ull};
  const Descriptor some{0b1011, 0, 1ull << 63, 0};
  EXPECT_EQ(Popcount(zero), 0);
  EXPECT_EQ(Popcount(ones), 256);
  EXPECT_EQ(Popcount(some), 4);
  EXPECT_EQ(HammingDistance(zero, ones), 256);
  EXPECT_EQ(HammingDistance(some, some), 0);
  EXPECT_EQ(HammingDistance(zero, some), 4);
}

TEST(Features, HammingMatchesBitByBitOracle) {
  auto rng = test::SeededRng(1);
  for (int trial = 0; trial < 100; ++trial) {
    const Descriptor a = RandomDescriptor(rng), b = RandomDescriptor(rng);
    int bits = 0;
    for (int w = 0; w < 4; ++w)
      for (int i = 0; i < 64; ++i) bits += ((a[w] >> i) & 1) != ((b[w] >> i) & 1);
    EXPECT_EQ(HammingDistance(a, b), bits);
  }
}

std::vector<cv::KeyPoint> GridKeypoints() {
  // 4 keypoints in the left half with high responses, 2 in the right half with low ones.
  std::vector<cv::KeyPoint> k;
  k.emplace_back(cv::Point2f(10, 10), 7, -1, 0.9f);
  k.emplace_back(cv::Point2f(20, 10), 7, -1, 0.8f);
  k.emplace_back(cv::Point2f(30, 10), 7, -1, 0.7f);
  k.emplace_back(cv::Point2f(40, 10), 7, -1, 0.6f);
  k.emplace_back(cv::Point2f(90, 10), 7, -1, 0.2f);
  k.emplace_back(cv::Point2f(95, 10), 7, -1, 0.1f);
  return k;
}

TEST(Features, RankingByResponsePopcountAndGrid) {
  const auto kps = GridKeypoints();
  std::vector<Descriptor> d(kps.size(), Descriptor{0, 0, 0, 0});
  d[5] = {~0ull, 0, 0, 0};  // most set bits
  d[3] = {0xFFull, 0, 0, 0};
  EXPECT_EQ(RankFeatures(kps, d, FeatureRanking::kResponse, 3, {100, 20}, 2, 1),
            (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(RankFeatures(kps, d, FeatureRanking::kPopcount, 2, {100, 20}, 2, 1),
            (std::vector<int>{5, 3}));
  // Grid 2x1: best of the left cell, best of the right cell, then second of each.
  EXPECT_EQ(RankFeatures(kps, d, FeatureRanking::kGridResponse, 4, {100, 20}, 2, 1),
            (std::vector<int>{0, 4, 1, 5}));
  // k larger than the count keeps everything once.
  auto all = RankFeatures(kps, d, FeatureRanking::kGridResponse, 100, {100, 20}, 2, 1);
  EXPECT_EQ(std::set<int>(all.begin(), all.end()).size(), kps.size());
}

TEST(Features, HighGradientMaskSelectsEdgesOnly) {
  cv::Mat img(128, 128, CV_8UC1, cv::Scalar(100));
  img(cv::Rect(64, 0, 64, 128)).setTo(200);  // vertical step edge at x = 64
  GradientMaskOptions o;
  o.dilate_radius = 2;
  const cv::Mat mask = HighGradientMask(img, o);
  EXPECT_EQ(mask.at<uint8_t>(50, 64), 255);
  EXPECT_EQ(mask.at<uint8_t>(50, 62), 255);  // within the dilation
  EXPECT_EQ(mask.at<uint8_t>(50, 20), 0);
  EXPECT_EQ(mask.at<uint8_t>(50, 110), 0);
  const cv::Mat flat(64, 64, CV_8UC1, cv::Scalar(7));
  EXPECT_EQ(cv::countNonZero(HighGradientMask(flat, o)), 0);
}

// HighGradientMask written the plain way (the definition in its header): central differences
// truncated to integers, float magnitude, per-block median + offset, dilation.
cv::Mat HighGradientMaskReference(const cv::Mat& gray, const GradientMaskOptions& o) {
  cv::Mat mag(gray.size(), CV_8UC1, cv::Scalar(0));
  for (int y = 1; y + 1 < gray.rows; ++y)
    for (int x = 1; x + 1 < gray.cols; ++x) {
      const int gx = (int(gray.at<uint8_t>(y, x + 1)) - int(gray.at<uint8_t>(y, x - 1))) / 2;
      const int gy = (int(gray.at<uint8_t>(y + 1, x)) - int(gray.at<uint8_t>(y - 1, x))) / 2;
      mag.at<uint8_t>(y, x) = static_cast<uint8_t>(std::sqrt(float(gx * gx + gy * gy)));
    }
  cv::Mat mask(gray.size(), CV_8UC1, cv::Scalar(0));
  for (int by = 0; by < gray.rows; by += o.block_size)
    for (int bx = 0; bx < gray.cols; bx += o.block_size) {
      const cv::Rect r =
          cv::Rect(bx, by, o.block_size, o.block_size) & cv::Rect(0, 0, gray.cols, gray.rows);
      const cv::Mat block = mag(r);
      std::vector<uint8_t> v(block.begin<uint8_t>(), block.end<uint8_t>());
      std::sort(v.begin(), v.end());
      const double median = v[(v.size() - 1) / 2];  // lower median, as the histogram walk
      const cv::Mat sel = block > median + o.threshold_offset;
      sel.copyTo(mask(r));
    }
  if (o.dilate_radius > 0) {
    const int k = 2 * o.dilate_radius + 1;
    cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }
  return mask;
}

TEST(Features, HighGradientMaskSimdMatchesScalar) {
  // Every width from 1 to 60 (the 16-pixel loop, its tail, rows shorter than one vector) and a
  // KITTI-sized one; full-range noise reaches the largest gradients (|d| = 255).
  cv::RNG rng(5);
  GradientMaskOptions o;
  o.block_size = 8;
  for (int cols = 1; cols <= 60; ++cols) {
    for (int blur : {0, 1}) {
      cv::Mat img(23, cols, CV_8UC1);
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
      if (blur) cv::GaussianBlur(img, img, cv::Size(3, 3), 0.8);
      const cv::Mat diff = HighGradientMask(img, o) != HighGradientMaskReference(img, o);
      ASSERT_EQ(cv::countNonZero(diff), 0) << cols << " columns, blur " << blur;
    }
  }
  cv::Mat big(370, 1226, CV_8UC1);
  rng.fill(big, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(big, big, cv::Size(5, 5), 1.2);
  const GradientMaskOptions d;
  EXPECT_EQ(cv::countNonZero(HighGradientMask(big, d) != HighGradientMaskReference(big, d)), 0);
  // A non-continuous input (a ROI: row stride > width).
  const cv::Mat roi = big(cv::Rect(3, 5, 517, 200));
  EXPECT_EQ(cv::countNonZero(HighGradientMask(roi, d) != HighGradientMaskReference(roi, d)), 0);
}

cv::Mat TexturedImage(uint64_t seed) {
  cv::Mat img(240, 320, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  for (int i = 0; i < 40; ++i)
    cv::rectangle(img, cv::Rect(rng.uniform(0, 300), rng.uniform(0, 220), 20, 20),
                  cv::Scalar(rng.uniform(0, 255)), cv::FILLED);
  return img;
}

using test::SmallCamera;

TEST(Features, ExtractKeepsAtMostKAndIsDeterministic) {
  const cv::Mat img = TexturedImage(3);
  const CameraIntrinsics cam = SmallCamera();
  FeatureInput in;
  in.image = &img;
  in.intrinsics = &cam;
  FeatureOptions o;
  o.max_features = 15;
  KeyframeRecord a, b;
  ExtractInformativeFeatures(in, o, &a);
  ExtractInformativeFeatures(in, o, &b);
  ASSERT_EQ(a.size(), 15u);
  EXPECT_EQ(a.keypoints.size(), 15u);
  EXPECT_TRUE(a.depths.empty());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.descriptors[i], b.descriptors[i]);
    EXPECT_EQ(a.keypoints[i].x, b.keypoints[i].x);
    // Normalised coordinates of a pixel inside the 320x240 image.
    EXPECT_LE(std::abs(a.keypoints[i].x), 160.0 / 300.0 + 1e-6);
    EXPECT_LE(std::abs(a.keypoints[i].y), 120.0 / 300.0 + 1e-6);
  }
  // The paper's budget: K = 15 fits in 1 KiB, counted with inline and heap bytes.
  EXPECT_LE(a.Bytes(), 1024u);
  EXPECT_GE(a.Bytes(), sizeof(KeyframeRecord) + 15 * (32 + sizeof(CompactKeypoint)));
}

TEST(Features, PackedRecordOfAnExtractionFitsIn640BytesAndRoundTrips) {
  const cv::Mat img = TexturedImage(5);
  const CameraIntrinsics cam = SmallCamera();
  std::vector<cv::Point2f> pixels;
  std::vector<float> depths;
  for (int y = 20; y < 220; y += 4)
    for (int x = 20; x < 300; x += 4) {
      pixels.emplace_back(static_cast<float>(x), static_cast<float>(y));
      depths.push_back(2.0f + 0.01f * static_cast<float>(x));
    }
  FeatureInput in;
  in.image = &img;
  in.intrinsics = &cam;
  in.mapped_pixels = &pixels;
  in.mapped_depths = &depths;
  FeatureOptions o;
  o.max_features = 15;
  KeyframeRecord r;
  ExtractInformativeFeatures(in, o, &r);
  r.id = 7;
  r.timestamp = 12.5;
  r.has_pose = true;
  r.world_from_cam = Sim3d(1.3, Eigen::Quaterniond(0.9, 0.1, -0.3, 0.2).normalized(),
                           Eigen::Vector3d(40.0, -3.0, 120.0));
  r.focal_px = 300.0f;
  ASSERT_EQ(r.size(), 15u);
  ASSERT_TRUE(r.has_depths());
  const PackedKeyframe p = PackRecord(r);
  EXPECT_LE(p.Bytes(), 640u);  // the paper's K with pose, ids, keypoints and depths
  EXPECT_LT(p.Bytes(), r.Bytes() * 3 / 4);
  const KeyframeRecord u = UnpackRecord(p);
  EXPECT_EQ(u.id, r.id);
  EXPECT_EQ(u.timestamp, r.timestamp);
  EXPECT_EQ(u.descriptors, r.descriptors);
  for (size_t i = 0; i < r.size(); ++i) {
    EXPECT_NEAR(u.keypoints[i].x, r.keypoints[i].x, 1e-4);  // 0.03 px at f = 300
    EXPECT_NEAR(u.keypoints[i].y, r.keypoints[i].y, 1e-4);
    EXPECT_NEAR(u.depths[i], r.depths[i], 5e-4 * r.depths[i]);
  }
  EXPECT_LT((u.world_from_cam.translation - r.world_from_cam.translation).norm(), 1e-4);
  const PackedKeyframe again = PackRecord(u);
  EXPECT_TRUE(
      std::equal(again.bytes().begin(), again.bytes().end(), p.bytes().begin(), p.bytes().end()));
}

TEST(Features, MaskRestrictsExtractionArea) {
  const cv::Mat img = TexturedImage(4);
  const CameraIntrinsics cam = SmallCamera();
  cv::Mat mask(img.size(), CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, 160, 240)).setTo(255);  // left half only
  FeatureInput in;
  in.image = &img;
  in.intrinsics = &cam;
  in.mask = &mask;
  KeyframeRecord r;
  ExtractInformativeFeatures(in, FeatureOptions{}, &r);
  ASSERT_GT(r.size(), 5u);
  for (const auto& k : r.keypoints) EXPECT_LT(k.x, 0.0f);  // u < cx
}

TEST(Features, MappedPixelsGiveDepths) {
  const cv::Mat img = TexturedImage(5);
  const CameraIntrinsics cam = SmallCamera();
  // Every pixel on a coarse lattice is "mapped" with depth = 1 + u / 100.
  std::vector<cv::Point2f> pixels;
  std::vector<float> depths;
  for (int v = 0; v < 240; v += 2)
    for (int u = 0; u < 320; u += 2) {
      pixels.emplace_back(float(u), float(v));
      depths.push_back(1.0f + u / 100.0f);
    }
  FeatureInput in;
  in.image = &img;
  in.intrinsics = &cam;
  in.mapped_pixels = &pixels;
  in.mapped_depths = &depths;
  FeatureOptions o;
  o.max_features = 30;
  KeyframeRecord r;
  ExtractInformativeFeatures(in, o, &r);
  ASSERT_EQ(r.depths.size(), r.size());
  for (size_t i = 0; i < r.size(); ++i) {
    const double u = r.keypoints[i].x * 300 + 160;
    EXPECT_NEAR(r.depths[i], 1.0 + u / 100.0, 0.03);  // nearest lattice pixel within 1.5 px
  }
}

// The depth of a kept keypoint is the depth of the nearest mapped pixel with a depth within 3 px
// (checked against a brute-force scan over every mapped pixel), at the query's whole extraction
// (asymmetric matching) and with irregular, unknown (<= 0) and clustered depths.
TEST(Features, MappedDepthIsTheNearestMappedPixelWithin3PxLikeAFullScan) {
  const cv::Mat img = TexturedImage(7);
  const CameraIntrinsics cam = SmallCamera();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-5.0f, 325.0f), v(-5.0f, 245.0f), z(-0.5f, 9.0f);
  std::vector<cv::Point2f> pixels;
  std::vector<float> depths;
  for (int i = 0; i < 6000; ++i) {
    pixels.emplace_back(u(rng), v(rng));
    depths.push_back(z(rng));
  }
  FeatureInput in;
  in.image = &img;
  in.intrinsics = &cam;
  in.mapped_pixels = &pixels;
  in.mapped_depths = &depths;
  FeatureOptions o;
  o.max_features = 1000;
  KeyframeRecord r;
  ExtractInformativeFeatures(in, o, &r);
  ASSERT_GT(r.size(), 100u);
  ASSERT_EQ(r.depths.size(), r.size());
  int with_depth = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    const float px = static_cast<float>(r.keypoints[i].x * cam.fx + cam.cx);
    const float py = static_cast<float>(r.keypoints[i].y * cam.fy + cam.cy);
    float best = 1e9f, second = 1e9f;
    float best_depth = 0.0f;
    for (size_t m = 0; m < pixels.size(); ++m) {
      if (depths[m] <= 0) continue;
      const float d = std::hypot(pixels[m].x - px, pixels[m].y - py);
      if (d < best) {
        second = best;
        best = d;
        best_depth = depths[m];
      } else if (d < second) {
        second = d;
      }
    }
    // Keypoints are stored normalised: their pixel is known to ~1e-4 px; skip the ambiguous.
    if (std::abs(best - 3.0f) < 1e-3f || second - best < 1e-3f) continue;
    if (best < 3.0f) {
      EXPECT_EQ(r.depths[i], best_depth) << "keypoint " << i << " nearest " << best << " px";
      ++with_depth;
    } else {
      EXPECT_EQ(r.depths[i], 0.0f) << "keypoint " << i << " nearest " << best << " px";
    }
  }
  EXPECT_GT(with_depth, 50);
}

TEST(Features, OptionsCheck) {
  FeatureOptions o;
  EXPECT_NO_THROW(o.Check());
  o.max_features = 2;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = FeatureOptions{};
  o.orb_candidates = o.max_features - 1;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  EXPECT_THROW(ParseFeatureRanking("best"), std::invalid_argument);
  EXPECT_EQ(ParseFeatureRanking("grid"), FeatureRanking::kGridResponse);
  const cv::Mat color(10, 10, CV_8UC3);
  const CameraIntrinsics cam = SmallCamera();
  FeatureInput in;
  in.image = &color;
  in.intrinsics = &cam;
  KeyframeRecord r;
  EXPECT_THROW(ExtractInformativeFeatures(in, FeatureOptions{}, &r), std::invalid_argument);
}

// ---- kFast ORB backend vs OpenCV's masked cv::ORB (docs/DETECTOR.md, Speed) ----

cv::Mat KittiFrame(int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.png", index);
  return cv::imread((test::DataDir() / "kitti07_first160" / "image_0" / name).string(),
                    cv::IMREAD_GRAYSCALE);
}

// KITTI 04-12 cam0 (kitti07_first160), from the one table in the synthetic module.
CameraIntrinsics KittiCamera() { return synthetic::KittiCam0Intrinsics(7); }

// Number of kept features that differ (descriptor, position, angle or octave), or -1 when the
// counts differ.
int RecordDifferences(const KeyframeRecord& a, const KeyframeRecord& b) {
  if (a.size() != b.size()) return -1;
  int d = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const auto& p = a.keypoints[i];
    const auto& q = b.keypoints[i];
    d += a.descriptors[i] != b.descriptors[i] || p.x != q.x || p.y != q.y || p.angle != q.angle ||
         p.octave != q.octave;
  }
  return d;
}

TEST(Features, FastOrbMatchesOpenCvOrbOnKitti) {
  SL_REQUIRE_DATA("kitti07_first160");
  const CameraIntrinsics cam = KittiCamera();
  // Measured on all 160 frames x 3 rankings (144,000 features): 0 differences. Frames here cover
  // the start, middle and end of the sequence; every ranking, with and without the area mask.
  for (int index : {0, 55, 159}) {
    const cv::Mat img = KittiFrame(index);
    ASSERT_FALSE(img.empty());
    for (FeatureRanking ranking :
         {FeatureRanking::kResponse, FeatureRanking::kPopcount, FeatureRanking::kGridResponse}) {
      for (bool area : {true, false}) {
        FeatureInput in;
        in.image = &img;
        in.intrinsics = &cam;
        FeatureOptions o;
        o.ranking = ranking;
        o.use_gradient_mask = area;
        o.orb_backend = OrbBackend::kOpenCv;
        KeyframeRecord reference, fast;
        ExtractInformativeFeatures(in, o, &reference);
        o.orb_backend = OrbBackend::kFast;
        ExtractInformativeFeatures(in, o, &fast);
        ASSERT_EQ(reference.size(), 300u);
        EXPECT_EQ(RecordDifferences(reference, fast), 0)
            << "frame " << index << " ranking " << ToString(ranking) << " area " << area;
      }
    }
  }
}

TEST(Features, FastOrbKeepsOnlyKeypointsInsideTheMask) {
  const CameraIntrinsics cam = SmallCamera();
  for (uint64_t seed : {4, 6}) {
    const cv::Mat img = TexturedImage(seed);
    // An irregular area: left half plus a disc on the right.
    cv::Mat mask(img.size(), CV_8UC1, cv::Scalar(0));
    mask(cv::Rect(0, 0, 160, 240)).setTo(255);
    cv::circle(mask, cv::Point(250, 120), 45, cv::Scalar(255), cv::FILLED);
    FeatureInput in;
    in.image = &img;
    in.intrinsics = &cam;
    in.mask = &mask;
    FeatureOptions o;
    o.max_features = 1000;  // keep every candidate
    o.orb_backend = OrbBackend::kFast;
    KeyframeRecord fast, reference;
    ExtractInformativeFeatures(in, o, &fast);
    ASSERT_GT(fast.size(), 20u);
    for (const auto& k : fast.keypoints) {
      // Back to pixels (no distortion). A level-L keypoint is inside the level's mask, i.e. its
      // full-resolution position is inside the area up to the level's resampling (< scale px).
      const double u = k.x * cam.fx + cam.cx, v = k.y * cam.fy + cam.cy;
      const int r = k.octave == 0 ? 0 : static_cast<int>(std::ceil(std::pow(1.2, k.octave)));
      const cv::Rect near =
          cv::Rect(int(std::lround(u)) - r, int(std::lround(v)) - r, 2 * r + 1, 2 * r + 1) &
          cv::Rect(0, 0, mask.cols, mask.rows);
      EXPECT_GT(cv::countNonZero(mask(near)), 0) << "keypoint at " << u << ", " << v;
    }
    o.orb_backend = OrbBackend::kOpenCv;
    ExtractInformativeFeatures(in, o, &reference);
    EXPECT_EQ(RecordDifferences(reference, fast), 0) << "seed " << seed;
  }
}

TEST(Features, OrbBackendNames) {
  EXPECT_EQ(ParseOrbBackend("fast"), OrbBackend::kFast);
  EXPECT_EQ(ParseOrbBackend("opencv"), OrbBackend::kOpenCv);
  EXPECT_STREQ(ToString(OrbBackend::kFast), "fast");
  EXPECT_THROW(ParseOrbBackend("sift"), std::invalid_argument);
  EXPECT_EQ(FeatureOptions{}.orb_backend, OrbBackend::kFast);
}

}  // namespace
}  // namespace sparseloop
