#include "masked_orb.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "linear_exact_resize.h"
#include "sparseloop/core/check.h"

namespace sparseloop::internal {
namespace {

constexpr int kEdgeThreshold = 31;  // cv::ORB default, also its border filter
constexpr int kPatchSize = 31;      // cv::ORB default (BRIEF patch and orientation patch)
constexpr int kHarrisBlock = 7;     // cv::ORB's Harris block
constexpr float kHarrisK = 0.04f;

struct Workspace {
  std::vector<cv::Mat> image;         // level images (level 0 aliases the caller's image)
  std::vector<cv::Mat> mask;          // level masks (level 0 aliases the caller's mask)
  std::vector<float> scale;           // full-resolution / level scale
  std::vector<cv::Point2f> level_pt;  // per returned keypoint: its level coordinates
  std::vector<cv::KeyPoint> level_kps;
  MaskedOrbParams params;
  cv::Ptr<cv::ORB> orb;        // descriptors only (compute with provided keypoints)
  LinearExactResizer resizer;  // cv::resize(INTER_LINEAR_EXACT), bit-identical, tables cached
};

Workspace& ThreadWorkspace() {
  thread_local Workspace ws;
  return ws;
}

// ORB's per-level quota: geometric in 1 / scale factor, the last level gets the remainder.
std::vector<int> FeaturesPerLevel(int nfeatures, double scale_factor, int levels) {
  std::vector<int> n(levels);
  const float factor = static_cast<float>(1.0 / scale_factor);
  float per_scale =
      nfeatures * (1 - factor) / (1 - static_cast<float>(std::pow(double(factor), double(levels))));
  int sum = 0;
  for (int l = 0; l < levels - 1; ++l) {
    n[l] = cvRound(per_scale);
    sum += n[l];
    per_scale *= factor;
  }
  n[levels - 1] = std::max(nfeatures - sum, 0);
  return n;
}

// Harris corner measure on a 7x7 block of 3x3 Sobel gradients (same arithmetic and float
// evaluation order as cv::ORB, so that the retained set is identical).
void HarrisResponse(const cv::Mat& img, std::vector<cv::KeyPoint>* kps) {
  const int step = static_cast<int>(img.step);
  const int r = kHarrisBlock / 2;
  float scale = (1 << 2) * kHarrisBlock * 255.0f;
  scale = 1.0f / scale;
  const float scale4 = scale * scale * scale * scale;
  for (auto& kp : *kps) {
    const int x0 = cvRound(kp.pt.x) - r;
    const int y0 = cvRound(kp.pt.y) - r;
    int a = 0, b = 0, c = 0;
    for (int dy = 0; dy < kHarrisBlock; ++dy) {
      const uint8_t* p = img.ptr<uint8_t>(y0 + dy) + x0;
      for (int dx = 0; dx < kHarrisBlock; ++dx, ++p) {
        const int ix =
            (p[1] - p[-1]) * 2 + (p[-step + 1] - p[-step - 1]) + (p[step + 1] - p[step - 1]);
        const int iy =
            (p[step] - p[-step]) * 2 + (p[step - 1] - p[-step - 1]) + (p[step + 1] - p[-step + 1]);
        a += ix * ix;
        b += iy * iy;
        c += ix * iy;
      }
    }
    kp.response =
        ((float)a * b - (float)c * c - kHarrisK * ((float)a + b) * ((float)a + b)) * scale4;
  }
}

// End of each row of the circular orientation patch (symmetric), as ORB builds it.
std::vector<int> CircleRowEnds(int half) {
  std::vector<int> umax(half + 2);
  const int vmax = cvFloor(half * std::sqrt(2.f) / 2 + 1);
  const int vmin = cvCeil(half * std::sqrt(2.f) / 2);
  for (int v = 0; v <= vmax; ++v) umax[v] = cvRound(std::sqrt(double(half) * half - v * v));
  for (int v = half, v0 = 0; v >= vmin; --v) {
    while (umax[v0] == umax[v0 + 1]) ++v0;
    umax[v] = v0;
    ++v0;
  }
  return umax;
}

// Intensity-centroid orientation (Rosin) in degrees, on the unblurred level image.
float CentroidAngle(const cv::Mat& img, cv::Point2f pt, int half, const std::vector<int>& umax) {
  const uint8_t* center = &img.at<uint8_t>(cvRound(pt.y), cvRound(pt.x));
  const int step = static_cast<int>(img.step);
  int m01 = 0, m10 = 0;
  for (int u = -half; u <= half; ++u) m10 += u * center[u];
  for (int v = 1; v <= half; ++v) {
    int vsum = 0;
    const int d = umax[v];
    for (int u = -d; u <= d; ++u) {
      const int plus = center[u + v * step], minus = center[u - v * step];
      vsum += plus - minus;
      m10 += u * (plus + minus);
    }
    m01 += v * vsum;
  }
  return cv::fastAtan2(float(m01), float(m10));
}

}  // namespace

void DetectMaskedOrb(const cv::Mat& image, const cv::Mat& mask, const MaskedOrbParams& params,
                     std::vector<cv::KeyPoint>* keypoints) {
  SL_CHECK(image.type() == CV_8UC1 && keypoints != nullptr);
  SL_CHECK(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == image.size()));
  Workspace& ws = ThreadWorkspace();
  const int levels = params.levels;
  const double scale_factor = params.scale_factor;  // float -> double, as cv::ORB stores it
  ws.params = params;
  ws.image.resize(levels);
  ws.mask.resize(levels);
  ws.scale.resize(levels);
  const std::vector<int> quota = FeaturesPerLevel(params.nfeatures, scale_factor, levels);
  keypoints->clear();
  ws.level_pt.clear();
  std::vector<cv::KeyPoint>& kps = ws.level_kps;
  for (int l = 0; l < levels; ++l) {
    ws.scale[l] = static_cast<float>(std::pow(scale_factor, double(l)));
    const cv::Size sz(cvRound(image.cols / ws.scale[l]), cvRound(image.rows / ws.scale[l]));
    if (l == 0) {
      ws.image[0] = image;
      ws.mask[0] = mask;
    } else {
      // cv::ORB resizes each level from the previous one (INTER_LINEAR_EXACT); the level Mats
      // are reused per thread.
      ws.resizer.Resize(ws.image[l - 1], sz, &ws.image[l]);
      if (!mask.empty()) {
        ws.resizer.Resize(ws.mask[l - 1], sz, &ws.mask[l]);
        cv::threshold(ws.mask[l], ws.mask[l], 254, 0, cv::THRESH_TOZERO);
      } else {
        ws.mask[l].release();
      }
    }
    const cv::Mat& img = ws.image[l];
    kps.clear();
    // FAST only where a keypoint can survive the border filter below ([31, size - 31)), plus the
    // 3 px FAST ring and 1 px for the non-maximum suppression neighbours: identical keypoints,
    // and by area ~30 % less FAST work over the pyramid (the border is a large share of the small
    // levels).
    constexpr int kPad = kEdgeThreshold - 4;
    const cv::Rect roi = cv::Rect(kPad, kPad, img.cols - 2 * kPad, img.rows - 2 * kPad) &
                         cv::Rect(0, 0, img.cols, img.rows);
    if (roi.width > 6 && roi.height > 6) {
      cv::FAST(img(roi), kps, params.fast_threshold, true, cv::FastFeatureDetector::TYPE_9_16);
      for (auto& k : kps) k.pt += cv::Point2f(float(roi.x), float(roi.y));
    }
    if (!mask.empty()) {
      const cv::Mat& m = ws.mask[l];
      kps.erase(std::remove_if(kps.begin(), kps.end(),
                               [&](const cv::KeyPoint& k) {
                                 return m.at<uint8_t>(int(k.pt.y + 0.5f), int(k.pt.x + 0.5f)) == 0;
                               }),
                kps.end());
    }
    cv::KeyPointsFilter::runByImageBorder(kps, img.size(), kEdgeThreshold);
    cv::KeyPointsFilter::retainBest(kps, 2 * quota[l]);
    HarrisResponse(img, &kps);
    cv::KeyPointsFilter::retainBest(kps, quota[l]);
    const float s = ws.scale[l];
    for (auto& k : kps) {
      k.octave = l;
      k.size = kPatchSize * s;
      ws.level_pt.push_back(k.pt);
      k.pt *= s;
      keypoints->push_back(k);
    }
  }
}

void ComputeMaskedOrbDescriptors(const std::vector<int>& indices, const MaskedOrbParams& params,
                                 std::vector<cv::KeyPoint>* keypoints,
                                 std::vector<Descriptor>* descriptors) {
  Workspace& ws = ThreadWorkspace();
  SL_CHECK(keypoints != nullptr && descriptors != nullptr);
  SL_CHECK(ws.level_pt.size() == keypoints->size());
  static const std::vector<int> umax = CircleRowEnds(kPatchSize / 2);
  SL_CHECK(ws.params.levels == params.levels && ws.params.scale_factor == params.scale_factor);
  descriptors->assign(indices.size(), Descriptor{0, 0, 0, 0});
  if (!ws.orb) {
    ws.orb =
        cv::ORB::create(500, 1.2f, 1, kEdgeThreshold, 0, 2, cv::ORB::HARRIS_SCORE, kPatchSize, 20);
  }
  // Crop margin: BRIEF samples lie within 13 * sqrt(2) < 19 px of the keypoint and the 7x7
  // Gaussian reads 3 px further; cv::ORB also drops keypoints within 31 px of the crop border.
  constexpr int kMargin = kEdgeThreshold + 1;
  for (int l = 0; l < params.levels; ++l) {
    const cv::Mat& img = ws.image[l];
    std::vector<cv::KeyPoint> local;
    int x0 = INT32_MAX, y0 = INT32_MAX, x1 = INT32_MIN, y1 = INT32_MIN;
    for (size_t j = 0; j < indices.size(); ++j) {
      cv::KeyPoint& k = (*keypoints)[indices[j]];
      if (k.octave != l) continue;
      const cv::Point2f p = ws.level_pt[indices[j]];
      k.angle = CentroidAngle(img, p, kPatchSize / 2, umax);  // on the unblurred level, as ORB
      cv::KeyPoint lk(p, k.size, k.angle, k.response, 0, static_cast<int>(j));
      local.push_back(lk);
      x0 = std::min(x0, cvRound(p.x));
      y0 = std::min(y0, cvRound(p.y));
      x1 = std::max(x1, cvRound(p.x));
      y1 = std::max(y1, cvRound(p.y));
    }
    if (local.empty()) continue;
    const cv::Rect crop = cv::Rect(cv::Point(x0 - kMargin, y0 - kMargin),
                                   cv::Point(x1 + kMargin + 1, y1 + kMargin + 1)) &
                          cv::Rect(0, 0, img.cols, img.rows);
    for (auto& k : local) k.pt -= cv::Point2f(float(crop.x), float(crop.y));
    // A ROI: cv::ORB extends it with the real neighbouring pixels where there are any, so the
    // blurred patch is the one cv::ORB computes on the whole level.
    cv::Mat desc;
    const size_t n = local.size();
    ws.orb->compute(img(crop), local, desc);
    SL_CHECK_MSG(local.size() == n && desc.rows == static_cast<int>(n),
                 "masked ORB: {} of {} keypoints lost in descriptor computation", n - local.size(),
                 n);
    for (size_t i = 0; i < local.size(); ++i)
      std::memcpy((*descriptors)[local[i].class_id].data(), desc.ptr(static_cast<int>(i)), 32);
  }
  // Do not keep the caller's image and mask alive in the thread-local workspace.
  ws.image[0].release();
  ws.mask[0].release();
}

}  // namespace sparseloop::internal
