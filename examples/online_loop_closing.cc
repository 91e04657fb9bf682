// The README's "Online use" example, compiled with the tests so that it cannot go stale.
//   online_loop_closing DIR   (a KITTI-layout folder: image_0/, times.txt, calib.txt and the
//                              vSLAM's raw poses in DIR/poses_raw.txt, e.g. `sparseloop render`)
// feeds DIR's frames as keyframes and prints the loop events and the corrected poses.
#include <cstdio>

#include <opencv2/imgcodecs.hpp>

#include "sparseloop/io/dataset.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/runtime/loop_closing.h"

using namespace sparseloop;

// [online-use]
void CloseLoopsOnline(const std::vector<KeyframeInput>& keyframes) {
  LoopClosing closing(LoopClosing::Options{}, [](const PoseCorrection& c) {
    // Background thread, after every solve: c.ids[i] -> c.world_from_keyframe[i].
    std::fprintf(stderr, "solve %llu: %zu loops\n", (unsigned long long)c.revision, c.num_loops);
  });
  for (const KeyframeInput& keyframe : keyframes) {         // image, intrinsics, raw pose, id, time
    const LoopEvent event = closing.AddKeyframe(keyframe);  // detection runs here
    if (event.result.detected())
      std::printf("loop %lld -> %lld\n", (long long)event.result.query_id,
                  (long long)event.result.match_id);
    // Any thread, any time: the latest correction of a keyframe.
    if (std::optional<KeyframeCorrection> pose = closing.CorrectedPose(keyframe.id))
      std::printf("  corrected x = %.3f (solve %llu)\n", pose->world_from_keyframe.translation.x(),
                  (unsigned long long)pose->revision);
  }
  closing.Finish();  // final solve, joins the background thread
  const CorrectedKeyframes all = closing.Corrections();
  std::printf("%zu keyframes corrected by solve %llu\n", all.ids.size(),
              (unsigned long long)all.revision);
}
// [online-use]

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: online_loop_closing DIR\n");
    return 2;
  }
  const Dataset dataset = OpenDataset(std::string("kitti:") + argv[1]);
  const Trajectory raw = ReadTrajectory(std::filesystem::path(argv[1]) / "poses_raw.txt");
  std::vector<KeyframeInput> keyframes;
  for (size_t i = 0; i < dataset.frames.size() && i < raw.poses.size(); ++i) {
    KeyframeInput k;
    k.id = dataset.frames[i].index;
    k.timestamp = dataset.frames[i].timestamp;
    k.image = cv::imread(dataset.frames[i].image_path.string(), cv::IMREAD_GRAYSCALE);
    k.intrinsics = dataset.intrinsics;
    k.world_from_cam = Sim3d(raw.poses[i].world_from_cam);
    keyframes.push_back(std::move(k));
  }
  CloseLoopsOnline(keyframes);
  return 0;
}
