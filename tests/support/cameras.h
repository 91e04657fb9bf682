#pragma once
// The pinhole cameras of the synthetic unit tests (no distortion).
#include "sparseloop/core/camera.h"

namespace sparseloop::test {

// focal length f (fx = fy) in pixels, a width x height image, principal point (cx, cy).
inline CameraIntrinsics PinholeCamera(double f, int width, int height, double cx, double cy) {
  CameraIntrinsics k;
  k.fx = k.fy = f;
  k.cx = cx;
  k.cy = cy;
  k.width = width;
  k.height = height;
  return k;
}

// 320 x 240, f = 300, principal point at the centre: the default of the detector unit tests.
inline CameraIntrinsics SmallCamera() { return PinholeCamera(300.0, 320, 240, 160.0, 120.0); }

}  // namespace sparseloop::test
