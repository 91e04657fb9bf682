#include "bag/message_convert.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sparseloop/core/quaternion.h"

namespace sparseloop::bag_internal {

namespace {
// Largest image side taken from a message (width and height are uint32 there): what an int holds.
constexpr int64_t kMaxSide = std::numeric_limits<int>::max();
}  // namespace

cv::Mat DecodeGray(const ImageData& m) {
  cv::Mat gray;
  if (m.header.compressed) {
    if (!m.data.empty()) {
      gray = cv::imdecode(
          cv::Mat(1, static_cast<int>(m.data.size()), CV_8UC1, const_cast<uint8_t*>(m.data.data())),
          cv::IMREAD_GRAYSCALE);
    }
    if (gray.empty()) {
      throw MessageError{"an image OpenCV decodes",
                         fmt::format("'{}' data of {} bytes that do not decode", m.header.encoding,
                                     m.data.size())};
    }
    return gray;
  }
  const std::string& e = m.header.encoding;
  const int channels = e == "mono8" || e == "8UC1"                   ? 1
                       : e == "mono16" || e == "16UC1"               ? -2
                       : e == "bgr8" || e == "rgb8" || e == "8UC3"   ? 3
                       : e == "bgra8" || e == "rgba8" || e == "8UC4" ? 4
                                                                     : 0;
  if (channels == 0) {
    throw MessageError{"encoding mono8, 8UC1, mono16, 16UC1, bgr8, rgb8, bgra8 or rgba8",
                       fmt::format("'{}'", e)};
  }
  const int64_t w64 = m.header.width, h64 = m.header.height;
  const int64_t row = w64 * std::abs(channels);
  if (w64 <= 0 || h64 <= 0 || w64 > kMaxSide || h64 > kMaxSide || m.step < row ||
      m.step > std::numeric_limits<int>::max() ||
      m.step * h64 > static_cast<int64_t>(m.data.size())) {
    throw MessageError{
        fmt::format("{}x{} {} pixels in rows of step {} (>= {})", w64, h64, e, m.step, row),
        fmt::format("{} bytes of data", m.data.size())};
  }
  const int w = static_cast<int>(w64), h = static_cast<int>(h64);
  auto* data = const_cast<uint8_t*>(m.data.data());
  if (channels == -2) {
    cv::Mat wide = cv::Mat(h, w, CV_16UC1, data, m.step).clone();
    if (m.big_endian) {
      for (int r = 0; r < h; ++r) {
        auto* p = wide.ptr<uint16_t>(r);
        for (int c = 0; c < w; ++c) p[c] = static_cast<uint16_t>((p[c] >> 8) | (p[c] << 8));
      }
    }
    wide.convertTo(gray, CV_8UC1, 1.0 / 256.0);
  } else {
    cv::Mat view(h, w, CV_8UC(channels), data, m.step);
    if (channels == 1) {
      gray = view.clone();
    } else {
      const bool rgb = e.rfind("rgb", 0) == 0;
      cv::cvtColor(view, gray,
                   channels == 3 ? (rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY)
                                 : (rgb ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY));
    }
  }
  return gray;
}

CameraIntrinsics IntrinsicsFromCameraInfo(const CameraInfoMessage& c) {
  CameraIntrinsics k;
  k.fx = c.k[0];
  k.cx = c.k[2];
  k.fy = c.k[4];
  k.cy = c.k[5];
  if (c.width < 0 || c.height < 0 || c.width > kMaxSide || c.height > kMaxSide) {
    throw MessageError{fmt::format("an image size of at most {0}x{0} pixels", kMaxSide),
                       fmt::format("{}x{}", c.width, c.height)};
  }
  k.width = static_cast<int>(c.width);
  k.height = static_cast<int>(c.height);
  const bool any = std::any_of(c.d.begin(), c.d.end(), [](double v) { return v != 0.0; });
  if (any && (c.distortion_model == "plumb_bob" || c.distortion_model == "radtan")) {
    k.distortion_model = DistortionModel::kRadialTangential;
    k.distortion = c.d;
  } else if (any && c.distortion_model == "equidistant") {
    k.distortion_model = DistortionModel::kEquidistant;
    k.distortion = c.d;
  } else if (any) {
    throw MessageError{"distortion_model plumb_bob or equidistant",
                       fmt::format("'{}'", c.distortion_model)};
  }
  try {
    k.Check();
  } catch (const std::invalid_argument& e) {
    throw MessageError{"valid intrinsics", e.what()};
  }
  return k;
}

Rigid3d PoseOf(const PoseMessage& m) {
  const Eigen::Quaterniond q = QuaternionFromXyzw(m.orientation_xyzw[0], m.orientation_xyzw[1],
                                                  m.orientation_xyzw[2], m.orientation_xyzw[3]);
  if (!(std::abs(q.norm() - 1.0) < 1e-3)) {
    throw MessageError{"a unit quaternion", fmt::format("norm {}", q.norm())};
  }
  const Eigen::Vector3d t(m.position[0], m.position[1], m.position[2]);
  if (!t.allFinite()) throw MessageError{"a finite position", "not finite"};
  return Rigid3d(q.normalized(), t);
}

}  // namespace sparseloop::bag_internal
