#pragma once
// Image-sequence datasets: frames (image path, time, optional ground-truth pose) plus intrinsics.
// Specs and folder layouts (documented in docs/FORMATS.md):
//   "kitti:DIR"   DIR/image_0/NNNNNN.png, DIR/times.txt, DIR/calib.txt (P0), optional poses
//   "tum:DIR"     DIR/rgb.txt, optional DIR/groundtruth.txt (nearest time within tum_max_dt)
//   "euroc:DIR"   DIR/mav0/cam0/{data.csv,sensor.yaml,data/*.png}, optional
//                 DIR/mav0/state_groundtruth_estimate0/data.csv
//   "images:DIR"  sorted *.png/jpg/jpeg/pgm/bmp; intrinsics from options, poses optional
//   "rosbag:FILE.bag?image=TOPIC&..."  a ROS 1 bag (sparseloop/bag/rosbag_dataset.h; opened by
//                 OpenRosbagDataset, or OpenDatasetSpec in pipeline/dataset_source.h, not here)
// A bad spec or a missing required option throws std::invalid_argument; a missing or malformed
// file throws FileError.
//
// Opening also reads the header of every frame's image (PNG, JPEG, PGM/PPM, BMP; no decoding), so
// that a bad image is reported by name before any frame is processed (docs/FORMATS.md):
//  - an image smaller than kMinImageSide pixels a side, or larger than kMaxImagePixels: FileError
//    naming the image;
//  - an image whose size differs from the intrinsics' width x height, or, when those are unknown,
//    from the first image's: FileError naming the image and the size expected (unknown width and
//    height are then filled in from the first image);
//  - a JPEG that does not end with the EOI marker FF D9 (a truncated file, which decoders return
//    half-decoded): FileError naming the image;
//  - a principal point outside the image: std::invalid_argument naming where the intrinsics came
//    from (DatasetOptions::intrinsics_name, a calibration file, ...).
// An image whose header cannot be read (missing, corrupt, other format) is left to the decoder:
// `RunPipeline` skips it (skip_unreadable_frames).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sparseloop/core/camera.h"
#include "sparseloop/core/rigid3.h"
#include "sparseloop/core/trajectory.h"

namespace sparseloop {

struct DatasetFrame {
  int64_t index = 0;       // 0-based position in the sequence
  double timestamp = 0.0;  // seconds (images: equal to index)
  std::filesystem::path image_path;
  std::optional<Rigid3d> gt_world_from_cam;  // ground-truth pose when known
};

// An 8-bit gray image, row-major without padding (io has no OpenCV).
struct GrayImage {
  int width = 0;                // pixels
  int height = 0;               // pixels
  std::vector<uint8_t> pixels;  // width * height bytes
};

// Images that are not files (the messages of a bag): the loader that opened the dataset decodes
// them. ReadGray throws FileError naming the container and the message when one cannot be read.
// Safe to call from one thread at a time per dataset.
class DatasetImageReader {
 public:
  virtual ~DatasetImageReader() = default;
  virtual GrayImage ReadGray(const DatasetFrame& frame) const = 0;
};

struct Dataset {
  std::string kind;  // "kitti", "tum", "euroc", "images" or "rosbag"
  std::filesystem::path root;
  CameraIntrinsics intrinsics;
  // Where `intrinsics` came from, for messages: DatasetOptions::intrinsics_name, a calibration file
  // (KITTI calib.txt, EuRoC sensor.yaml) or "the TUM freiburgN intrinsics".
  std::string intrinsics_source;
  std::vector<DatasetFrame> frames;
  std::filesystem::path gt_path;  // the file the ground truth came from (empty when none)
  // Null: every frame's image_path is an image file. Set: images come from this reader
  // (image_path then only names the frame for messages and output files).
  std::shared_ptr<const DatasetImageReader> image_reader;
  // Raw vSLAM poses the dataset itself carries (a rosbag: pose topic), timestamped, in time
  // order; empty when none. `raw_poses_source` names them for messages ("FILE.bag topic /pose").
  Trajectory raw_poses;
  std::string raw_poses_source;

  // True when at least one frame has a ground-truth pose.
  bool has_gt() const;
  // The frames that have a ground-truth pose, with their timestamps and frame indices.
  Trajectory GtTrajectory() const;
};

struct DatasetOptions {
  // Overrides the intrinsics from the dataset (required for "images:", and for "tum:" when the
  // folder name does not name freiburg1/2/3).
  std::optional<CameraIntrinsics> intrinsics;
  // How messages name `intrinsics`: a program sets what its user typed (the CLI: "--intrinsics").
  std::string intrinsics_name = "DatasetOptions::intrinsics";
  // Ground-truth trajectory file (any ReadTrajectory format, auto-detected); overrides the
  // dataset's own GT. kitti/images: matched by frame index; tum/euroc: by nearest timestamp.
  std::filesystem::path poses;
  double tum_max_dt = 0.02;     // seconds, max |t_image - t_gt| for tum association
  double euroc_max_dt = 0.005;  // seconds, same for euroc (GT at 200 Hz)
  // EuRoC GT is the body (IMU) pose. True: convert to the camera with T_BS from sensor.yaml
  // (world_from_cam = world_from_body * body_from_cam). False: keep the body pose.
  bool euroc_gt_in_camera_frame = true;
  double rosbag_max_dt = 0.01;  // seconds, max |t_image - t_pose| for rosbag: ground truth

  void Check() const;
};

// spec = "<kind>:<DIR>".
Dataset OpenDataset(const std::string& spec, const DatasetOptions& options = {});

// Each frame gets the GT pose nearest in time within max_dt (core/time_association.h,
// TimePairing::kNearest); returns how many frames got one. The dataset loaders' GT association.
size_t AttachGtByTime(std::vector<DatasetFrame>& frames, const Trajectory& gt, double max_dt);

// Width and height of a PNG image from its IHDR chunk (no decoding). FileError when the file is
// missing or is not a PNG.
struct ImageSize {
  int width = 0;   // pixels
  int height = 0;  // pixels
};
ImageSize ReadPngSize(const std::filesystem::path& path);

// Width and height from the header of a PNG, JPEG (first SOF marker), PGM/PPM/PBM or BMP file, no
// decoding. nullopt when the file cannot be opened or its header is none of these, or is cut
// short (the decoder decides what to do with it); FileError for a PNG header of zero size.
std::optional<ImageSize> ReadImageSize(const std::filesystem::path& path);

// Images OpenDataset accepts: at least kMinImageSide pixels a side (ORB's 31-pixel patch, and an
// 8-level pyramid that must not shrink to nothing), at most kMaxImagePixels pixels (16384^2; 256
// MiB of 8-bit gray, below OpenCV's own CV_IO_MAX_IMAGE_PIXELS).
inline constexpr int kMinImageSide = 32;
inline constexpr int64_t kMaxImagePixels = int64_t{1} << 28;

// The intrinsics of the TUM RGB-D Kinects (640x480), from the dataset's documentation:
// 1 -> freiburg1, 2 -> freiburg2 (both radtan k1 k2 p1 p2 k3), 3 -> freiburg3 (no distortion).
// Other values throw std::invalid_argument.
CameraIntrinsics TumFreiburgIntrinsics(int freiburg);

// A camera description parsed from an EuRoC/Kalibr sensor.yaml (the small YAML subset those files
// use: "key: value", "key: [a, b, ...]" lists possibly spanning lines, and a "T_BS:" block with
// "data: [16 numbers]").
struct EurocCameraInfo {
  CameraIntrinsics intrinsics;
  std::optional<Rigid3d> body_from_cam;  // T_BS when present
};
EurocCameraInfo ReadEurocSensorYaml(const std::filesystem::path& path);

}  // namespace sparseloop
