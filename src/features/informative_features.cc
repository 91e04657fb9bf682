#include "sparseloop/features/informative_features.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <string>
#include <unordered_map>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "masked_orb.h"
#include "sparseloop/core/check.h"

namespace sparseloop {

const char* ToString(FeatureRanking ranking) {
  switch (ranking) {
    case FeatureRanking::kPopcount:
      return "popcount";
    case FeatureRanking::kResponse:
      return "response";
    case FeatureRanking::kGridResponse:
      return "grid";
  }
  return "unknown";
}

FeatureRanking ParseFeatureRanking(const std::string& name) {
  if (name == "popcount") return FeatureRanking::kPopcount;
  if (name == "response") return FeatureRanking::kResponse;
  if (name == "grid") return FeatureRanking::kGridResponse;
  SL_CHECK_MSG(false, "feature ranking must be popcount, response or grid, got '{}'", name);
  return FeatureRanking::kResponse;
}

const char* ToString(OrbBackend backend) {
  switch (backend) {
    case OrbBackend::kOpenCv:
      return "opencv";
    case OrbBackend::kFast:
      return "fast";
  }
  return "unknown";
}

OrbBackend ParseOrbBackend(const std::string& name) {
  if (name == "opencv") return OrbBackend::kOpenCv;
  if (name == "fast") return OrbBackend::kFast;
  SL_CHECK_MSG(false, "ORB backend must be opencv or fast, got '{}'", name);
  return OrbBackend::kFast;
}

void GradientMaskOptions::Check() const {
  SL_CHECK_MSG(block_size >= 4, "gradient.block_size must be >= 4 pixels, got {}", block_size);
  SL_CHECK_MSG(std::isfinite(threshold_offset) && threshold_offset >= 0,
               "gradient.threshold_offset must be >= 0, got {}", threshold_offset);
  SL_CHECK_MSG(dilate_radius >= 0 && dilate_radius <= 64,
               "gradient.dilate_radius must be in [0, 64] pixels, got {}", dilate_radius);
}

int FeatureOptions::MinImageSide() const {
  // The pyramid resizes each level to cvRound(side / scale^l) pixels (as cv::ORB): a level of 0
  // pixels is an OpenCV assertion, and an image smaller than the patch holds no feature.
  constexpr int kPatchSide = 31;
  const float top = static_cast<float>(std::pow(static_cast<float>(orb_scale_factor),
                                                static_cast<double>(std::max(orb_levels, 1) - 1)));
  int side = kPatchSide + 1;
  while (cvRound(side / top) < 1) ++side;
  return side;
}

void FeatureOptions::Check() const {
  SL_CHECK_MSG(max_features >= 5 && max_features <= 10000,
               "features.max_features (K) must be in [5, 10000], got {}", max_features);
  SL_CHECK_MSG(orb_candidates >= max_features,
               "features.orb_candidates ({}) must be >= max_features ({})", orb_candidates,
               max_features);
  SL_CHECK_MSG(orb_levels >= 1 && orb_levels <= 16,
               "features.orb_levels must be in [1, 16], got {}", orb_levels);
  SL_CHECK_MSG(orb_scale_factor > 1.0 && orb_scale_factor <= 2.0,
               "features.orb_scale_factor must be in (1, 2], got {}", orb_scale_factor);
  SL_CHECK_MSG(orb_fast_threshold >= 1 && orb_fast_threshold <= 255,
               "features.orb_fast_threshold must be in [1, 255], got {}", orb_fast_threshold);
  // grid_cols * grid_rows cells are allocated per keyframe (and the product must fit an int).
  SL_CHECK_MSG(grid_cols >= 1 && grid_rows >= 1 && grid_cols <= 1000 && grid_rows <= 1000,
               "features.grid must be from 1x1 to 1000x1000 cells, got {}x{}", grid_cols,
               grid_rows);
  gradient.Check();
}

size_t KeyframeRecord::Bytes() const {
  return sizeof(KeyframeRecord) + descriptors.capacity() * sizeof(Descriptor) +
         keypoints.capacity() * sizeof(CompactKeypoint) + depths.capacity() * sizeof(float);
}

PackedKeyframe PackRecord(const KeyframeRecord& r) {
  SL_CHECK_MSG(r.keypoints.size() == r.descriptors.size(),
               "keyframe {}: {} keypoints for {} descriptors", r.id, r.keypoints.size(),
               r.descriptors.size());
  PackedKeyframe::Fields f;
  f.id = r.id;
  f.timestamp = r.timestamp;
  f.has_pose = r.has_pose;
  if (r.has_pose) f.world_from_cam = r.world_from_cam;
  f.focal_px = r.focal_px;
  f.descriptors = r.descriptors;
  f.keypoints.reserve(2 * r.keypoints.size());
  for (const CompactKeypoint& k : r.keypoints) {
    f.keypoints.push_back(k.x);
    f.keypoints.push_back(k.y);
  }
  f.depths = r.depths;
  return PackedKeyframe::Pack(f);
}

KeyframeRecord UnpackRecord(const PackedKeyframe& packed) {
  KeyframeRecord r;
  r.id = packed.id();
  r.timestamp = packed.timestamp();
  r.has_pose = packed.has_pose();
  r.world_from_cam = packed.world_from_cam();
  r.focal_px = packed.focal_px();
  const auto d = packed.descriptors();
  r.descriptors.assign(d.begin(), d.end());
  r.keypoints.resize(packed.size());
  for (size_t i = 0; i < packed.size(); ++i) {
    r.keypoints[i].x = packed.keypoint_x(i);
    r.keypoints[i].y = packed.keypoint_y(i);
  }
  if (packed.has_depths()) {
    r.depths.resize(packed.size());
    for (size_t i = 0; i < packed.size(); ++i) r.depths[i] = packed.depth(i);
  }
  return r;
}

namespace {

// Gradient magnitude (central differences, L2), clamped to [0, 255]; the border is 0. The
// buffer is the calling thread's, reused by its next call.
const cv::Mat& GradientMagnitude(const cv::Mat& gray) {
  const int rows = gray.rows;
  const int cols = gray.cols;
  // |gx|, |gy| <= 127, so floor(sqrt(gx^2 + gy^2)) comes from a table (exactly the float sqrt;
  // 4x faster than calling it).
  static const std::vector<uint8_t> kSqrt = [] {
    std::vector<uint8_t> t(2 * 127 * 127 + 1);
    for (size_t i = 0; i < t.size(); ++i)
      t[i] = static_cast<uint8_t>(std::min(static_cast<int>(std::sqrt(float(i))), 255));
    return t;
  }();
  // The magnitude buffer is reused per thread (a fresh zeroed 1226x370 buffer per keyframe cost
  // a memset and, on this VM, page faults); every pixel is written below, the border as 0.
  thread_local cv::Mat mag;
  mag.create(rows, cols, CV_8UC1);
  mag.row(0).setTo(0);
  mag.row(rows - 1).setTo(0);
  for (int y = 1; y + 1 < rows; ++y) {
    mag.at<uint8_t>(y, 0) = 0;
    mag.at<uint8_t>(y, cols - 1) = 0;
  }
  for (int y = 1; y + 1 < rows; ++y) {
    const uint8_t* up = gray.ptr<uint8_t>(y - 1);
    const uint8_t* mid = gray.ptr<uint8_t>(y);
    const uint8_t* down = gray.ptr<uint8_t>(y + 1);
    uint8_t* out = mag.ptr<uint8_t>(y);
    int x = 1;
#if CV_SIMD128
    // 16 pixels at a time, the same arithmetic: |trunc(d / 2)| = |d| >> 1, the sum of squares
    // (<= 2 * 127^2) in 16 bits, IEEE single-precision sqrt (what the table holds), truncated.
    // Bit-identical to the scalar loop (Features.HighGradientMaskSimdMatchesScalar).
    for (; x + 17 <= cols; x += 16) {  // reads mid[x + 16], writes out[x + 15] <= cols - 2
      const cv::v_uint8x16 dx8 = cv::v_absdiff(cv::v_load(mid + x + 1), cv::v_load(mid + x - 1));
      const cv::v_uint8x16 dy8 = cv::v_absdiff(cv::v_load(down + x), cv::v_load(up + x));
      cv::v_uint16x8 dx[2], dy[2];
      cv::v_expand(dx8, dx[0], dx[1]);
      cv::v_expand(dy8, dy[0], dy[1]);
      cv::v_int16x8 m[2];
      for (int h = 0; h < 2; ++h) {
        const cv::v_uint16x8 gx = cv::v_shr<1>(dx[h]), gy = cv::v_shr<1>(dy[h]);
        const cv::v_uint16x8 sq = cv::v_mul_wrap(gx, gx) + cv::v_mul_wrap(gy, gy);
        cv::v_uint32x4 s[2];
        cv::v_expand(sq, s[0], s[1]);
        const cv::v_int32x4 r0 =
            cv::v_trunc(cv::v_sqrt(cv::v_cvt_f32(cv::v_reinterpret_as_s32(s[0]))));
        const cv::v_int32x4 r1 =
            cv::v_trunc(cv::v_sqrt(cv::v_cvt_f32(cv::v_reinterpret_as_s32(s[1]))));
        m[h] = cv::v_pack(r0, r1);
      }
      cv::v_store(out + x, cv::v_pack_u(m[0], m[1]));
    }
#endif
    for (; x + 1 < cols; ++x) {
      const int gx = (int(mid[x + 1]) - int(mid[x - 1])) / 2;
      const int gy = (int(down[x]) - int(up[x])) / 2;
      out[x] = kSqrt[gx * gx + gy * gy];
    }
  }
  return mag;
}

// Per-block median via a histogram, threshold = median + offset (DSO's pixel selector idea).
cv::Mat ThresholdByBlockMedian(const cv::Mat& mag, const GradientMaskOptions& options) {
  const int rows = mag.rows;
  const int cols = mag.cols;
  cv::Mat mask(rows, cols, CV_8UC1);  // every pixel is written: the blocks tile the image
  const int b = options.block_size;
  for (int by = 0; by < rows; by += b) {
    for (int bx = 0; bx < cols; bx += b) {
      const int y1 = std::min(by + b, rows);
      const int x1 = std::min(bx + b, cols);
      int hist[256] = {0};
      for (int y = by; y < y1; ++y) {
        const uint8_t* row = mag.ptr<uint8_t>(y);
        for (int x = bx; x < x1; ++x) ++hist[row[x]];
      }
      const int n = (y1 - by) * (x1 - bx);
      int acc = 0;
      int median = 0;
      for (; median < 256; ++median) {
        acc += hist[median];
        if (2 * acc >= n) break;
      }
      // mag > median + offset (cv::THRESH_BINARY's rule), as an integer bound on the 8-bit mag.
      const double th = median + options.threshold_offset;
      const int above = th < 0 ? 0 : static_cast<int>(std::floor(th)) + 1;  // mag >= above
      for (int y = by; y < y1; ++y) {
        const uint8_t* row = mag.ptr<uint8_t>(y);
        uint8_t* out = mask.ptr<uint8_t>(y);
        if (above > 255) {
          std::fill(out + bx, out + x1, uint8_t{0});
          continue;
        }
        // An 8-bit comparison (the loop vectorises): mag >= above <=> mag > above - 1.
        const auto a8 = static_cast<uint8_t>(above);
        for (int x = bx; x < x1; ++x) out[x] = row[x] >= a8 ? 255 : 0;
      }
    }
  }
  return mask;
}

}  // namespace

cv::Mat HighGradientMask(const cv::Mat& gray, const GradientMaskOptions& options) {
  options.Check();
  SL_CHECK_MSG(!gray.empty() && gray.type() == CV_8UC1, "HighGradientMask needs a CV_8UC1 image");
  cv::Mat mask = ThresholdByBlockMedian(GradientMagnitude(gray), options);
  if (options.dilate_radius > 0) {
    const int k = 2 * options.dilate_radius + 1;
    cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }
  return mask;
}

std::vector<int> RankFeatures(const std::vector<cv::KeyPoint>& keypoints,
                              const std::vector<Descriptor>& descriptors, FeatureRanking ranking,
                              int k, cv::Size image_size, int grid_cols, int grid_rows) {
  SL_CHECK(keypoints.size() == descriptors.size());
  SL_CHECK(k >= 0);
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  // Ties broken by index so that the ranking is a total order (deterministic).
  auto by_response = [&](int a, int b) {
    if (keypoints[a].response != keypoints[b].response)
      return keypoints[a].response > keypoints[b].response;
    return a < b;
  };
  switch (ranking) {
    case FeatureRanking::kPopcount: {
      std::vector<int> pc(descriptors.size());
      for (size_t i = 0; i < descriptors.size(); ++i) pc[i] = Popcount(descriptors[i]);
      std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
        if (pc[a] != pc[b]) return pc[a] > pc[b];
        return by_response(a, b);
      });
      break;
    }
    case FeatureRanking::kResponse:
      std::sort(order.begin(), order.end(), by_response);
      break;
    case FeatureRanking::kGridResponse: {
      std::sort(order.begin(), order.end(), by_response);
      const int cells = grid_cols * grid_rows;
      std::vector<std::vector<int>> per_cell(cells);
      for (int i : order) {
        const auto& p = keypoints[i].pt;
        int cx = std::clamp(int(p.x * grid_cols / std::max(1, image_size.width)), 0, grid_cols - 1);
        int cy =
            std::clamp(int(p.y * grid_rows / std::max(1, image_size.height)), 0, grid_rows - 1);
        per_cell[cy * grid_cols + cx].push_back(i);
      }
      std::vector<int> out;
      for (size_t round = 0; out.size() < order.size(); ++round) {
        for (int c = 0; c < cells; ++c) {
          if (round < per_cell[c].size()) out.push_back(per_cell[c][round]);
        }
      }
      order = std::move(out);
      break;
    }
  }
  if (static_cast<int>(order.size()) > k) order.resize(k);
  return order;
}

namespace {

std::vector<cv::Point2f> Undistort(const std::vector<cv::Point2f>& pixels,
                                   const CameraIntrinsics& intr) {
  std::vector<cv::Point2f> out;
  if (pixels.empty()) return out;
  if (intr.distortion_model == DistortionModel::kNone) {
    out.reserve(pixels.size());
    for (const auto& p : pixels)
      out.emplace_back(float((p.x - intr.cx) / intr.fx), float((p.y - intr.cy) / intr.fy));
    return out;
  }
  cv::Matx33d k(intr.fx, 0, intr.cx, 0, intr.fy, intr.cy, 0, 0, 1);
  cv::Mat dist(intr.distortion, true);
  if (intr.distortion_model == DistortionModel::kEquidistant) {
    cv::fisheye::undistortPoints(pixels, out, k, dist);
  } else {
    // Many iterations: the default 5 do not converge near the corners of strong (EuRoC-like,
    // k1 = -0.28) radial distortion.
    cv::undistortPoints(
        pixels, out, k, dist, cv::noArray(), cv::noArray(),
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  }
  return out;
}

}  // namespace

namespace {

// Extraction area: caller's mask, else dilated mapped pixels, else semi-dense selection (empty:
// the whole image).
cv::Mat ExtractionMask(const FeatureInput& input, const FeatureOptions& options) {
  const cv::Mat& image = *input.image;
  const cv::Size size = image.size();
  if (input.mask != nullptr && !input.mask->empty()) {
    SL_CHECK_MSG(input.mask->size() == size && input.mask->type() == CV_8UC1,
                 "mask must be CV_8UC1 of the image size");
    return *input.mask;
  }
  if (input.mapped_pixels != nullptr && !input.mapped_pixels->empty()) {
    cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
    const int r = std::max(1, options.gradient.dilate_radius);
    for (const auto& p : *input.mapped_pixels) {
      cv::rectangle(mask, cv::Point(int(p.x) - r, int(p.y) - r),
                    cv::Point(int(p.x) + r, int(p.y) + r), cv::Scalar(255), cv::FILLED);
    }
    return mask;
  }
  if (options.use_gradient_mask) return HighGradientMask(image, options.gradient);
  return cv::Mat();
}

// ORB keypoints in the mask, the ranked indices of the K kept (`keep`) and descriptors (`all`:
// of every keypoint, or only of the kept ones where the ranking needs none).
void DetectAndRank(const cv::Mat& image, const cv::Mat& mask, const FeatureOptions& options,
                   std::vector<cv::KeyPoint>* keypoints_out, std::vector<Descriptor>* all_out,
                   std::vector<int>* keep_out) {
  const cv::Size size = image.size();
  std::vector<cv::KeyPoint>& keypoints = *keypoints_out;
  std::vector<Descriptor>& all = *all_out;
  std::vector<int>& keep = *keep_out;
  if (options.orb_backend == OrbBackend::kOpenCv) {
    auto orb = cv::ORB::create(options.orb_candidates, static_cast<float>(options.orb_scale_factor),
                               options.orb_levels, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31,
                               options.orb_fast_threshold);
    cv::Mat desc;
    orb->detectAndCompute(image, mask, keypoints, desc);
    all.resize(keypoints.size());
    for (size_t i = 0; i < keypoints.size(); ++i) std::memcpy(all[i].data(), desc.ptr(int(i)), 32);
    keep = RankFeatures(keypoints, all, options.ranking, options.max_features, size,
                        options.grid_cols, options.grid_rows);
  } else {
    // Same keypoints as the masked cv::ORB call above (docs/DETECTOR.md, Speed). BRIEF is needed
    // before ranking only for popcount; response / grid rank first and describe the K kept.
    internal::MaskedOrbParams params;
    params.nfeatures = options.orb_candidates;
    params.scale_factor = static_cast<float>(options.orb_scale_factor);
    params.levels = options.orb_levels;
    params.fast_threshold = options.orb_fast_threshold;
    internal::DetectMaskedOrb(image, mask, params, &keypoints);
    if (options.ranking == FeatureRanking::kPopcount) {
      std::vector<int> every(keypoints.size());
      std::iota(every.begin(), every.end(), 0);
      internal::ComputeMaskedOrbDescriptors(every, params, &keypoints, &all);
      keep = RankFeatures(keypoints, all, options.ranking, options.max_features, size,
                          options.grid_cols, options.grid_rows);
    } else {
      const std::vector<Descriptor> unused(keypoints.size());  // ranking ignores descriptors
      keep = RankFeatures(keypoints, unused, options.ranking, options.max_features, size,
                          options.grid_cols, options.grid_rows);
      std::vector<Descriptor> kept;
      internal::ComputeMaskedOrbDescriptors(keep, params, &keypoints, &kept);
      all.assign(keypoints.size(), Descriptor{0, 0, 0, 0});
      for (size_t j = 0; j < keep.size(); ++j) all[keep[j]] = kept[j];
    }
  }
}

// Depth of each kept keypoint (`pixels`): the nearest mapped pixel within 3 px that has a depth
// (0 when none).
std::vector<float> DepthsFromMappedPixels(const FeatureInput& input,
                                          const std::vector<cv::Point2f>& pixels) {
  const size_t n = pixels.size();
  std::vector<float> depths(n, 0.0f);
  const auto& mp = *input.mapped_pixels;
  const auto& md = *input.mapped_depths;
  // Mapped pixels with a depth bucketed in 3 px cells: a keypoint looks at its cell and the 8
  // around it (all pixels within 3 px), in input order, so ties resolve as a full scan would
  // (the last pixel at the smallest distance wins). Linear in keypoints + mapped pixels, which
  // matters for the query's whole extraction (asymmetric matching: 1,000 keypoints).
  constexpr float kCell = 3.0f;
  auto cell_of = [&](float v) { return static_cast<int64_t>(std::floor(v / kCell)); };
  auto key = [](int64_t cx, int64_t cy) { return (cx << 32) ^ (cy & 0xffffffff); };
  std::unordered_map<int64_t, std::vector<uint32_t>> cells;
  for (size_t m = 0; m < mp.size(); ++m)
    if (md[m] > 0 && std::isfinite(mp[m].x) && std::isfinite(mp[m].y))
      cells[key(cell_of(mp[m].x), cell_of(mp[m].y))].push_back(static_cast<uint32_t>(m));
  std::vector<uint32_t> near;
  for (size_t j = 0; j < n; ++j) {
    near.clear();
    const int64_t cx = cell_of(pixels[j].x), cy = cell_of(pixels[j].y);
    for (int64_t dy = -1; dy <= 1; ++dy)
      for (int64_t dx = -1; dx <= 1; ++dx) {
        const auto it = cells.find(key(cx + dx, cy + dy));
        if (it != cells.end()) near.insert(near.end(), it->second.begin(), it->second.end());
      }
    std::sort(near.begin(), near.end());
    float best = 9.0f;  // squared pixel radius
    for (uint32_t m : near) {
      const float dx = mp[m].x - pixels[j].x;
      const float dy = mp[m].y - pixels[j].y;
      const float d2 = dx * dx + dy * dy;
      if (d2 <= best) {
        best = d2;
        depths[j] = md[m];
      }
    }
  }
  return depths;
}

}  // namespace

void ExtractInformativeFeatures(const FeatureInput& input, const FeatureOptions& options,
                                KeyframeRecord* record) {
  options.Check();
  SL_CHECK_MSG(record != nullptr, "record must not be null");
  SL_CHECK_MSG(input.image != nullptr && !input.image->empty(), "image must not be empty");
  SL_CHECK_MSG(input.image->type() == CV_8UC1, "image must be 8-bit grayscale (CV_8UC1)");
  SL_CHECK_MSG(input.intrinsics != nullptr, "intrinsics are required");
  input.intrinsics->Check();
  const cv::Mat mask = ExtractionMask(input, options);
  if (input.mapped_depths != nullptr) {
    SL_CHECK_MSG(input.mapped_pixels != nullptr &&
                     input.mapped_pixels->size() == input.mapped_depths->size(),
                 "mapped_depths needs mapped_pixels of the same length");
  }

  std::vector<cv::KeyPoint> keypoints;
  std::vector<Descriptor> all;  // descriptors of `keypoints` (kOpenCv, popcount) or of `keep`
  std::vector<int> keep;
  DetectAndRank(*input.image, mask, options, &keypoints, &all, &keep);

  std::vector<cv::Point2f> pixels;
  pixels.reserve(keep.size());
  for (int i : keep) pixels.push_back(keypoints[i].pt);
  const std::vector<cv::Point2f> normalised = Undistort(pixels, *input.intrinsics);

  record->descriptors.clear();
  record->keypoints.clear();
  record->depths.clear();
  record->descriptors.reserve(keep.size());
  record->keypoints.reserve(keep.size());
  for (size_t j = 0; j < keep.size(); ++j) {
    const auto& kp = keypoints[keep[j]];
    record->descriptors.push_back(all[keep[j]]);
    CompactKeypoint c;
    c.x = normalised[j].x;
    c.y = normalised[j].y;
    c.angle = static_cast<uint16_t>(std::lround(std::clamp(kp.angle, 0.0f, 359.99f) * 100.0f));
    c.octave = static_cast<uint8_t>(std::clamp(kp.octave, 0, 255));
    record->keypoints.push_back(c);
  }
  record->focal_px = static_cast<float>(0.5 * (input.intrinsics->fx + input.intrinsics->fy));

  if (input.mapped_depths != nullptr && !input.mapped_depths->empty()) {
    record->depths = DepthsFromMappedPixels(input, pixels);
  }
}

}  // namespace sparseloop
