#pragma once
// The castle views (test::LoadCastle) as detector input: view i + 1 with its exact pose as the
// raw pose, id and timestamp the view number.
#include <vector>

#include "real_data.h"
#include "sparseloop/loop/loop_detector.h"

namespace sparseloop::test {

inline KeyframeInput CastleKeyframe(const std::vector<Frame>& frames, size_t i) {
  KeyframeInput in;
  in.id = static_cast<int64_t>(i + 1);        // view number
  in.timestamp = static_cast<double>(in.id);  // keyframe timestamps must increase
  in.image = frames[i].image;
  in.intrinsics = frames[i].intrinsics;
  in.world_from_cam = Sim3d(frames[i].world_from_cam);
  return in;
}

}  // namespace sparseloop::test
