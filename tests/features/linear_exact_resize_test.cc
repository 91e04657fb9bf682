// features/linear_exact_resize: bit-identical to cv::resize(..., INTER_LINEAR_EXACT) (8-bit, one
// channel), with and without the vector loops, on every kind of size the ORB pyramids and users
// produce.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "features/linear_exact_resize.h"

namespace sparseloop::internal {
namespace {

int Differences(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return -1;
  return cv::countNonZero(a != b);
}

// Checks both loops (vector and scalar) against OpenCV on one source and output size.
void ExpectSameAsOpenCv(const cv::Mat& src, cv::Size size, LinearExactResizer* simd,
                        LinearExactResizer* scalar, const std::string& what) {
  cv::Mat expected, got_simd, got_scalar;
  cv::resize(src, expected, size, 0, 0, cv::INTER_LINEAR_EXACT);
  simd->Resize(src, size, &got_simd);
  scalar->Resize(src, size, &got_scalar);
  ASSERT_EQ(Differences(got_simd, expected), 0) << what << ": vector loops";
  ASSERT_EQ(Differences(got_scalar, expected), 0) << what << ": scalar loops";
}

cv::Mat Content(cv::Size size, int kind, cv::RNG* rng) {
  cv::Mat img(size, CV_8UC1);
  switch (kind) {
    case 0:  // full-range noise
      rng->fill(img, cv::RNG::UNIFORM, 0, 256);
      break;
    case 1:  // a binary mask (0 / 255), as the high-gradient area
      rng->fill(img, cv::RNG::UNIFORM, 0, 2);
      img *= 255;
      break;
    case 2:  // all 255: the largest fixed-point sums
      img.setTo(255);
      break;
    default:  // smooth
      rng->fill(img, cv::RNG::UNIFORM, 0, 256);
      cv::GaussianBlur(img, img, cv::Size(5, 5), 2.0);
  }
  return img;
}

TEST(LinearExactResize, MatchesOpenCvOnDownAndUpScales) {
  cv::RNG rng(11);
  LinearExactResizer simd(true), scalar(false);
  const std::vector<cv::Size> sources = {{1, 1},   {2, 1},   {1, 2},    {2, 2},  {3, 5},
                                         {7, 3},   {16, 9},  {17, 17},  {31, 8}, {40, 33},
                                         {64, 48}, {100, 7}, {255, 129}};
  for (const cv::Size& s : sources) {
    for (int kind = 0; kind < 4; ++kind) {
      const cv::Mat src = Content(s, kind, &rng);
      for (int trial = 0; trial < 12; ++trial) {
        const cv::Size d(1 + rng.uniform(0, 2 * s.width + 3), 1 + rng.uniform(0, 2 * s.height + 3));
        ExpectSameAsOpenCv(
            src, d, &simd, &scalar,
            cv::format("%dx%d -> %dx%d kind %d", s.width, s.height, d.width, d.height, kind));
      }
    }
  }
}

TEST(LinearExactResize, MatchesOpenCvOnOrbPyramidsOfCameraSizes) {
  // ORB's chain (each level from the previous one, size = round(level 0 / 1.2^l)) on KITTI,
  // EuRoC, TUM and castle sizes, image content and binary masks; one resizer for all (its cached
  // tables are shared between sizes).
  cv::RNG rng(3);
  LinearExactResizer simd(true), scalar(false);
  for (const cv::Size& s : {cv::Size(1226, 370), cv::Size(1241, 376), cv::Size(752, 480),
                            cv::Size(640, 480), cv::Size(768, 512)}) {
    for (int kind : {0, 1, 3}) {
      cv::Mat level = Content(s, kind, &rng);
      for (int l = 1; l < 8; ++l) {
        const double f = std::pow(1.2000000476837158, l);  // cv::ORB's float 1.2f as double
        const cv::Size d(cvRound(s.width / f), cvRound(s.height / f));
        ExpectSameAsOpenCv(level, d, &simd, &scalar,
                           cv::format("%dx%d level %d kind %d", s.width, s.height, l, kind));
        cv::Mat next;
        cv::resize(level, next, d, 0, 0, cv::INTER_LINEAR_EXACT);
        level = next;
      }
    }
  }
}

TEST(LinearExactResize, RoiInPlaceAndOpenCvsOtherPaths) {
  cv::RNG rng(8);
  LinearExactResizer simd(true), scalar(false);
  const cv::Mat big = Content(cv::Size(300, 200), 0, &rng);
  // A ROI (row stride larger than the width, taps next to the ROI not read).
  const cv::Mat roi = big(cv::Rect(13, 7, 217, 151));
  ExpectSameAsOpenCv(roi, cv::Size(181, 126), &simd, &scalar, "roi");
  // Equal size (OpenCV copies) and exactly half (OpenCV's INTER_AREA path).
  ExpectSameAsOpenCv(roi, roi.size(), &simd, &scalar, "same size");
  ExpectSameAsOpenCv(big, cv::Size(150, 100), &simd, &scalar, "half");
  // Output into the source Mat itself.
  cv::Mat expected;
  cv::resize(big, expected, cv::Size(250, 166), 0, 0, cv::INTER_LINEAR_EXACT);
  cv::Mat self = big.clone();
  simd.Resize(self, cv::Size(250, 166), &self);
  EXPECT_EQ(Differences(self, expected), 0);
  // An output that already has the size is reused, its old content overwritten.
  cv::Mat reused(cv::Size(250, 166), CV_8UC1, cv::Scalar(7));
  simd.Resize(big, cv::Size(250, 166), &reused);
  EXPECT_EQ(Differences(reused, expected), 0);
  // Other types go to cv::resize.
  cv::Mat color(40, 30, CV_8UC3), got, want;
  rng.fill(color, cv::RNG::UNIFORM, 0, 256);
  simd.Resize(color, cv::Size(25, 33), &got);
  cv::resize(color, want, cv::Size(25, 33), 0, 0, cv::INTER_LINEAR_EXACT);
  EXPECT_EQ(cv::norm(got, want, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace sparseloop::internal
