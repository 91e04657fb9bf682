#include "sparseloop/pipeline/kitti_sequence.h"

#include <atomic>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/timer.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop {

namespace fs = std::filesystem;
using synthetic::Photometric;
using synthetic::RenderedFrame;
using synthetic::RenderOptions;
using synthetic::World;

void SequenceOptions::Check() const {
  render.Check();
  if (photometric_drift) photometric.Check();
  drift.Check();
  mapped.Check();
  SL_CHECK_MSG(num_threads >= 1 && num_threads <= 256, "num_threads must be in [1, 256], got {}",
               num_threads);
  SL_CHECK_MSG(png_compression >= 0 && png_compression <= 9,
               "png_compression must be in [0, 9], got {}", png_compression);
}

namespace {

void WritePng(const fs::path& path, const cv::Mat& image, int compression) {
  std::vector<uchar> buffer;
  if (!cv::imencode(".png", image, buffer, {cv::IMWRITE_PNG_COMPRESSION, compression})) {
    throw FileError(path.string(), 0, "a PNG encoding", "cv::imencode failed");
  }
  WriteFileAtomically(path, [&](std::ostream& out) {
    out.write(reinterpret_cast<const char*>(buffer.data()),
              static_cast<std::streamsize>(buffer.size()));
  });
}

}  // namespace

void WriteKittiCalib(const fs::path& path, const CameraIntrinsics& camera) {
  constexpr double kBaseline = 0.54;  // metres, KITTI stereo baseline
  WriteFileAtomically(path, [&](std::ostream& out) {
    for (int i = 0; i < 4; ++i) {
      const double tx = (i % 2 == 1) ? -camera.fx * kBaseline : 0.0;
      out << fmt::format(
          "P{}: {:.12e} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e} "
          "{:.12e} {:.12e} {:.12e} {:.12e}\n",
          i, camera.fx, 0.0, camera.cx, tx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 0.0, 1.0, 0.0);
    }
  });
}

namespace {

// Frame i's files: image_0/NNNNNN.png, and depth_0 / mapped when the options ask for them.
void WriteFrameFiles(const fs::path& out_dir, const World& world, const CameraIntrinsics& camera,
                     const Trajectory& gt, const SequenceOptions& options,
                     const RenderOptions& render, double scale, int64_t i) {
  const Photometric photometric = options.photometric_drift
                                      ? synthetic::PhotometricForFrame(i, options.photometric)
                                      : Photometric{};
  RenderedFrame frame = synthetic::RenderFrame(world, camera, gt.poses[i].world_from_cam, render,
                                               photometric, static_cast<uint64_t>(i));
  const std::string stem = fmt::format("{:06d}", i);
  cv::Mat img(frame.image.height, frame.image.width, CV_8UC1, frame.image.pixels.data());
  WritePng(out_dir / "image_0" / (stem + ".png"), img, options.png_compression);
  if (options.write_depth) {
    cv::Mat depth16(frame.depth.height, frame.depth.width, CV_16UC1);
    for (int v = 0; v < depth16.rows; ++v)
      for (int u = 0; u < depth16.cols; ++u)
        depth16.at<uint16_t>(v, u) = static_cast<uint16_t>(
            std::clamp(std::lround(frame.depth.at(u, v) * 256.0), 0L, 65535L));
    WritePng(out_dir / "depth_0" / (stem + ".png"), depth16, options.png_compression);
  }
  if (options.write_mapped) {
    const auto pixels =
        synthetic::SelectMappedPixels(frame.image, frame.depth, scale, options.mapped);
    WriteFileAtomically(out_dir / "mapped" / (stem + ".txt"), [&](std::ostream& out) {
      out << "# u v depth_raw\n";
      for (const auto& p : pixels) out << fmt::format("{:.1f} {:.1f} {:.6g}\n", p.u, p.v, p.depth);
    });
  }
}

// Runs render_frame(i) for i in [0, total) on num_threads threads (the caller's included); the
// first exception stops the others and is rethrown. Returns the frames done.
int64_t ForEachFrameInParallel(int64_t total, int num_threads,
                               const std::function<void(int64_t)>& render_frame,
                               const std::function<void(int64_t, int64_t)>& progress) {
  std::atomic<int64_t> next{0};
  std::atomic<int64_t> done{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex mutex;
  auto worker = [&]() {
    try {
      for (int64_t i = next++; i < total && !failed; i = next++) {
        render_frame(i);
        const int64_t d = ++done;
        if (progress) {
          std::lock_guard<std::mutex> lock(mutex);
          progress(d, total);
        }
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!error) error = std::current_exception();
      failed = true;
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < num_threads; ++t) threads.emplace_back(worker);
  worker();
  for (auto& t : threads) t.join();
  if (error) std::rethrow_exception(error);
  return done;
}

}  // namespace

void WriteRawScale(const std::filesystem::path& path, const std::vector<double>& scale) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    for (const double s : scale) out << fmt::format("{:.9g}\n", s);
  });
}

SequenceResult WriteKittiSequence(const fs::path& out_dir, const World& world,
                                  const CameraIntrinsics& camera, const Trajectory& gt,
                                  const SequenceOptions& options,
                                  const std::optional<Trajectory>& raw,
                                  const std::function<void(int64_t, int64_t)>& progress) {
  options.Check();
  world.Check();
  camera.Check();
  SL_CHECK_MSG(camera.width > 0 && camera.height > 0, "camera needs a size");
  SL_CHECK_MSG(!gt.empty(), "ground-truth trajectory is empty");
  SL_CHECK_MSG(!raw || raw->size() == gt.size(),
               "raw trajectory has {} poses, ground truth {} (association by index)",
               raw ? raw->size() : 0, gt.size());
  Timer timer;
  std::error_code ec;
  for (const char* sub : {"image_0", "mapped", "depth_0"}) {
    if ((std::string(sub) == "mapped" && !options.write_mapped) ||
        (std::string(sub) == "depth_0" && !options.write_depth)) {
      continue;
    }
    fs::create_directories(out_dir / sub, ec);
    if (ec) throw FileError((out_dir / sub).string(), 0, "a writable folder", ec.message());
  }

  // Trajectories and metadata first (cheap), then the frames.
  Trajectory raw_traj;
  std::vector<double> scale;
  if (raw) {
    raw_traj = *raw;
    scale = synthetic::LocalScale(gt, raw_traj);
  } else {
    synthetic::DriftResult drift = synthetic::SimulateDrift(gt, options.drift);
    raw_traj = std::move(drift.raw);
    scale = std::move(drift.scale);
  }
  WriteTrajectory(out_dir / "poses_gt.txt", gt, TrajectoryFormat::kKitti);
  WriteTrajectory(out_dir / "poses.txt", gt, TrajectoryFormat::kKitti);
  WriteTrajectory(out_dir / "poses_raw.txt", raw_traj, TrajectoryFormat::kKitti);
  WriteRawScale(out_dir / "raw_scale.txt", scale);
  WriteFileAtomically(out_dir / "times.txt", [&](std::ostream& out) {
    for (const auto& p : gt.poses) out << FormatSeconds(p.timestamp) << "\n";
  });
  WriteKittiCalib(out_dir / "calib.txt", camera);

  RenderOptions render = options.render;
  render.num_threads = 1;
  const int64_t done = ForEachFrameInParallel(
      static_cast<int64_t>(gt.size()), options.num_threads,
      [&](int64_t i) { WriteFrameFiles(out_dir, world, camera, gt, options, render, scale[i], i); },
      progress);

  SequenceResult result;
  result.frames = done;
  result.seconds = timer.ElapsedMs() / 1000.0;
  result.frames_per_second = result.seconds > 0.0 ? result.frames / result.seconds : 0.0;
  Logger().info("wrote {} frames to {} in {:.1f} s ({:.1f} frames/s)", result.frames,
                out_dir.string(), result.seconds, result.frames_per_second);
  return result;
}

}  // namespace sparseloop
