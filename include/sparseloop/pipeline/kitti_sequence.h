#pragma once
// A rendered sequence (module synthetic) written into the KITTI odometry folder layout (read back
// by the io module's "kitti:DIR" loader). See docs/FORMATS.md, "Synthetic sequences":
//   DIR/image_0/NNNNNN.png   8-bit grayscale frames
//   DIR/times.txt            one timestamp (s) per frame
//   DIR/calib.txt            P0..P3 (P1/P3 with the KITTI stereo baseline 0.54 m, for tools that
//                            expect them; only P0 describes the rendered camera)
//   DIR/poses.txt            GT world_from_cam, KITTI 12 numbers (what "kitti:" picks up)
//   DIR/poses_gt.txt         the same GT (explicit name)
//   DIR/poses_raw.txt        the drifting "vSLAM" trajectory, KITTI 12 numbers, raw scale
//   DIR/mapped/NNNNNN.txt    optional: "u v depth_raw" per mapped pixel
//   DIR/depth_0/NNNNNN.png   optional: 16-bit depth, metres * 256 (KITTI depth convention), 0 = sky
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/trajectory.h"
#include "sparseloop/synthetic/renderer.h"
#include "sparseloop/synthetic/vslam_sim.h"
#include "sparseloop/synthetic/world.h"

namespace sparseloop {

struct SequenceOptions {
  synthetic::RenderOptions render;  // per-frame rendering (its num_threads is ignored)
  bool photometric_drift = true;    // exposure/gamma change along the sequence
  synthetic::PhotometricDriftOptions photometric;  // used when photometric_drift
  synthetic::DriftOptions drift;  // raw trajectory simulation (when no raw is given)
  bool write_mapped = true;       // write mapped/NNNNNN.txt
  synthetic::MappedPixelOptions mapped;
  bool write_depth = false;  // write depth_0/NNNNNN.png
  int num_threads = 2;       // frames rendered in parallel (output independent of it)
  int png_compression = 1;   // 0..9, zlib level of the PNGs (1: fast)
  void Check() const;
};

struct SequenceResult {
  enum class Status { kOk };
  Status status = Status::kOk;
  int64_t frames = 0;              // frames written
  double seconds = 0.0;            // wall-clock time of the whole write
  double frames_per_second = 0.0;  // frames / seconds
};

// `gt` gives one frame per pose (its timestamps go to times.txt). `raw`, when given, is a real
// estimate already associated to `gt` by index (same size); otherwise SimulateDrift(gt) is used.
// `progress(done, total)` is called after each frame (serialised, from any worker thread).
// Creates `out_dir` if needed; every file is written atomically. Throws FileError on I/O failure.
SequenceResult WriteKittiSequence(const std::filesystem::path& out_dir,
                                  const synthetic::World& world, const CameraIntrinsics& camera,
                                  const Trajectory& gt, const SequenceOptions& options,
                                  const std::optional<Trajectory>& raw = std::nullopt,
                                  const std::function<void(int64_t, int64_t)>& progress = {});

// Writes raw_scale.txt: one line per frame, the raw trajectory's scale there (raw units per GT
// metre; the simulated drift's own scale, or LocalScale's estimate for a given raw trajectory).
void WriteRawScale(const std::filesystem::path& path, const std::vector<double>& scale);

// Writes calib.txt with P0..P3 for `camera` (P1/P3 with baseline 0.54 m).
void WriteKittiCalib(const std::filesystem::path& path, const CameraIntrinsics& camera);

}  // namespace sparseloop
