// The bad-input table (docs/ROBUSTNESS.md). Every row asserts a clear error (exception type and
// message) or a status, and that what the detector already stored is intact afterwards: the
// keyframe count and stored bytes are unchanged by a rejected keyframe, and a later valid keyframe
// is still accepted.
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cameras.h"
#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/dataset.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/pipeline/dataset_source.h"
#include "sparseloop/pipeline/pipeline.h"
#include "sparseloop/posegraph/g2o.h"
#include "test_util.h"

namespace sparseloop {
namespace {

constexpr int kWidth = 640;
constexpr int kHeight = 480;

cv::Mat TexturedImage(uint64_t seed) {
  cv::Mat img(kHeight, kWidth, CV_8UC1, cv::Scalar(128));
  cv::RNG rng(seed);
  for (int i = 0; i < 300; ++i) {
    const cv::Point a(rng.uniform(0, kWidth), rng.uniform(0, kHeight));
    const cv::Point b = a + cv::Point(rng.uniform(-40, 40), rng.uniform(-40, 40));
    const int shade = rng.uniform(0, 256);
    if (i % 3 == 0) {
      cv::circle(img, a, rng.uniform(3, 25), cv::Scalar(shade), cv::FILLED);
    } else {
      cv::rectangle(img, a, b, cv::Scalar(shade), cv::FILLED);
    }
  }
  return img;
}

CameraIntrinsics Camera() {
  return test::PinholeCamera(500.0, kWidth, kHeight, kWidth / 2.0, kHeight / 2.0);
}

KeyframeInput ValidInput(int64_t id) {
  KeyframeInput in;
  in.id = id;
  in.timestamp = 0.1 * static_cast<double>(id);
  in.image = TexturedImage(1000 + id);
  in.intrinsics = Camera();
  in.world_from_cam = Sim3d(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.5 * id, 0, 0));
  return in;
}

class BadInput : public testing::Test {
 protected:
  void SetUp() override {
    for (int64_t id = 0; id < 3; ++id) ASSERT_NO_THROW(detector_.Process(ValidInput(id)));
    keyframes_ = detector_.num_keyframes();
    bytes_ = detector_.StoredBytes();
  }
  // Asserts that a rejected keyframe changed nothing and the detector still accepts the next one.
  void ExpectStateIntact() {
    EXPECT_EQ(detector_.num_keyframes(), keyframes_);
    EXPECT_EQ(detector_.StoredBytes(), bytes_);
    EXPECT_NO_THROW(detector_.Process(ValidInput(100)));
    EXPECT_EQ(detector_.num_keyframes(), keyframes_ + 1);
  }
  void ExpectRejected(const KeyframeInput& in, const std::string& message) {
    try {
      detector_.Process(in);
      ADD_FAILURE() << "accepted a bad keyframe; expected: " << message;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
    ExpectStateIntact();
  }

  LoopDetector detector_{LoopDetector::Options{}};
  size_t keyframes_ = 0;
  size_t bytes_ = 0;
};

TEST_F(BadInput, ZeroSizeImage) {
  KeyframeInput in = ValidInput(3);
  in.image = cv::Mat();
  ExpectRejected(in, "image must not be empty");
}

// A 1x1 image reached OpenCV's pyramid resize and came back as its raw assertion (the ROS node
// aborted on it): below ORB's patch, or a pyramid level of 0 pixels, the image is refused.
TEST_F(BadInput, TinyImage) {
  KeyframeInput in = ValidInput(3);
  in.intrinsics = test::PinholeCamera(1.0, 0, 0, 0.5, 0.5);  // no image size to compare with
  in.image = cv::Mat(31, 400, CV_8UC1, cv::Scalar(0));
  try {
    detector_.Process(in);
    ADD_FAILURE() << "a 400x31 image was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("image of 400x31 pixels is too small"), std::string::npos)
        << e.what();
  }
  in.image = cv::Mat(1, 1, CV_8UC1, cv::Scalar(0));
  ExpectRejected(in, "keyframe 3: image of 1x1 pixels is too small: expected at least 32x32");
  in.id = 101;
  in.timestamp = 1000.0;
  in.image = cv::Mat(32, 32, CV_8UC1, cv::Scalar(0));
  EXPECT_NO_THROW(detector_.Process(in));
  FeatureOptions coarse;
  EXPECT_EQ(coarse.MinImageSide(), 32);
  coarse.orb_levels = 16;
  coarse.orb_scale_factor = 2.0;  // the top level is cvRound(side / 32768) pixels (0.5 -> 0)
  EXPECT_EQ(coarse.MinImageSide(), 16385);
}

TEST_F(BadInput, WrongPixelType) {
  KeyframeInput in = ValidInput(3);
  cv::cvtColor(in.image, in.image, cv::COLOR_GRAY2BGR);
  ExpectRejected(in, "8-bit grayscale");
}

TEST_F(BadInput, WrongSizeImage) {
  KeyframeInput in = ValidInput(3);
  cv::resize(in.image, in.image, cv::Size(320, 240));
  ExpectRejected(in, "does not match the intrinsics");
}

TEST_F(BadInput, ImageWithoutTextureGivesNoFeaturesStatus) {
  KeyframeInput in = ValidInput(3);
  in.image = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(77));
  const LoopResult r = detector_.Process(in);
  EXPECT_EQ(r.status, LoopStatus::kNoFeatures);
  EXPECT_EQ(detector_.num_keyframes(), keyframes_ + 1);  // stored (empty) so ids stay consistent
  EXPECT_NO_THROW(detector_.Process(ValidInput(4)));
}

TEST_F(BadInput, NanPose) {
  KeyframeInput in = ValidInput(3);
  in.world_from_cam->translation.x() = std::numeric_limits<double>::quiet_NaN();
  ExpectRejected(in, "pose is not finite");
}

TEST_F(BadInput, InfPose) {
  KeyframeInput in = ValidInput(3);
  in.world_from_cam->translation.z() = std::numeric_limits<double>::infinity();
  ExpectRejected(in, "pose is not finite");
}

TEST_F(BadInput, NonUnitQuaternion) {
  KeyframeInput in = ValidInput(3);
  in.world_from_cam->rotation.coeffs() << 0.5, 0.5, 0.5, 0.9;  // |q| = 1.18
  ExpectRejected(in, "non-unit quaternion");
}

TEST_F(BadInput, NonMonotonicTimestamp) {
  KeyframeInput in = ValidInput(3);
  in.timestamp = 0.05;  // earlier than keyframe 2 (0.2 s)
  ExpectRejected(in, "timestamp");
}

TEST_F(BadInput, DuplicateTimestamp) {
  KeyframeInput in = ValidInput(3);
  in.timestamp = 0.2;  // same as keyframe 2
  ExpectRejected(in, "timestamp");
}

TEST_F(BadInput, DuplicateKeyframeId) {
  KeyframeInput in = ValidInput(2);
  in.timestamp = 0.3;
  ExpectRejected(in, "already processed");
}

TEST_F(BadInput, WrongIntrinsicsFocalLength) {
  KeyframeInput in = ValidInput(3);
  in.intrinsics.fx = -500;
  ExpectRejected(in, "fx must be positive");
}

TEST_F(BadInput, WrongIntrinsicsPrincipalPoint) {
  KeyframeInput in = ValidInput(3);
  in.intrinsics.cx = 5000;
  ExpectRejected(in, "principal point");
}

TEST_F(BadInput, EmptyMaskGivesNoFeaturesStatus) {
  KeyframeInput in = ValidInput(3);
  in.high_gradient_mask = cv::Mat::zeros(kHeight, kWidth, CV_8UC1);
  const LoopResult r = detector_.Process(in);
  EXPECT_EQ(r.status, LoopStatus::kNoFeatures);
  EXPECT_NO_THROW(detector_.Process(ValidInput(4)));
}

TEST_F(BadInput, FullMaskBehavesLikeNoMask) {
  KeyframeInput with_mask = ValidInput(3);
  with_mask.high_gradient_mask = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(255));
  detector_.Process(with_mask);
  LoopDetector::Options whole_image;
  whole_image.features.use_gradient_mask = false;
  LoopDetector reference(whole_image);
  reference.Process(ValidInput(3));
  // A mask covering everything extracts exactly what the whole image gives.
  EXPECT_EQ(detector_.record(3).size(), reference.record(3).size());
  EXPECT_EQ(detector_.record(3).descriptors, reference.record(3).descriptors);
}

TEST_F(BadInput, MaskOfWrongSize) {
  KeyframeInput in = ValidInput(3);
  in.high_gradient_mask = cv::Mat(10, 10, CV_8UC1, cv::Scalar(255));
  ExpectRejected(in, "mask");
}

TEST_F(BadInput, DepthsWithoutPixels) {
  KeyframeInput in = ValidInput(3);
  in.mapped_depths = {1.0f, 2.0f};
  ExpectRejected(in, "mapped_depths");
}

// A NaN or infinite mapped pixel (or depth) is refused naming the entry, as the CLI's reader
// refuses a non-finite number in a mapped-pixels file; a depth <= 0 stays "unknown".
TEST_F(BadInput, NonFiniteMappedPixel) {
  KeyframeInput in = ValidInput(3);
  in.mapped_pixels = {{10.0f, 10.0f}, {20.0f, std::numeric_limits<float>::infinity()}};
  EXPECT_THROW(detector_.Process(in), std::invalid_argument);
  in.mapped_pixels = {{10.0f, 10.0f}, {std::numeric_limits<float>::quiet_NaN(), 20.0f}};
  ExpectRejected(in, "mapped_pixels[1]: expected finite pixel coordinates");
}

TEST_F(BadInput, NonFiniteMappedDepth) {
  KeyframeInput in = ValidInput(3);
  in.mapped_pixels = {{10.0f, 10.0f}, {20.0f, 20.0f}};
  in.mapped_depths = {-1.0f, 0.0f};  // unknown
  EXPECT_NO_THROW(detector_.Process(in));
  in = ValidInput(4);
  in.mapped_pixels = {{10.0f, 10.0f}, {20.0f, 20.0f}};
  in.mapped_depths = {std::numeric_limits<float>::quiet_NaN(), 2.0f};
  keyframes_ = detector_.num_keyframes();
  bytes_ = detector_.StoredBytes();
  ExpectRejected(in, "mapped_depths[0]: expected a finite depth");
}

// Dataset-level rows: a missing or corrupt image in a sequence, and a pose file shorter than the
// image list.
class BadSequence : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::TempDir() / "seq";
    std::filesystem::create_directories(dir_ / "image_0");
    std::ofstream times(dir_ / "times.txt");
    std::ofstream poses(dir_ / "raw.txt");
    for (int i = 0; i < 6; ++i) {
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.png", i);
      cv::imwrite((dir_ / "image_0" / name).string(), TexturedImage(50 + i));
      times << 0.1 * i << "\n";
      poses << "1 0 0 " << 0.5 * i << " 0 1 0 0 0 0 1 0\n";
    }
    std::ofstream(dir_ / "calib.txt") << "P0: 500 0 320 0 0 500 240 0 0 0 1 0\n";
  }
  std::filesystem::path dir_;
};

TEST_F(BadSequence, CorruptAndMissingImagesAreSkippedAndCounted) {
  std::ofstream(dir_ / "image_0" / "000002.png") << "not a png at all";
  std::filesystem::remove(dir_ / "image_0" / "000004.png");
  std::ofstream(dir_ / "image_0" / "000004.png");  // zero bytes
  const Dataset d = OpenDataset("kitti:" + dir_.string());
  const Trajectory raw =
      MatchRawPosesToFrames(d, ReadTrajectory(dir_ / "raw.txt"), 0.02, dir_ / "raw.txt");
  PipelineOptions options;
  const PipelineResult r = RunPipeline(d, raw, options);
  EXPECT_EQ(r.skipped_frames, 2u);
  EXPECT_EQ(r.frame_results.size(), 4u);
  EXPECT_EQ(r.corrected.size(), 6u);  // every raw pose still gets an output pose
  options.skip_unreadable_frames = false;
  try {
    RunPipeline(d, raw, options);
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("000002.png"), std::string::npos) << e.what();
  }
}

// An image that cannot be opened is never handed to OpenCV (which printed its own "[ WARN:0@...]"
// line) and the error says why ("Permission denied" for a user; here the file went away after the
// dataset was opened); a file that opens but does not decode says so.
TEST_F(BadSequence, UnreadableImageSaysWhy) {
  std::ofstream(dir_ / "image_0" / "000002.png") << "not a png at all";
  const Dataset d = OpenDataset("kitti:" + dir_.string());
  std::filesystem::remove(dir_ / "image_0" / "000003.png");
  EXPECT_EQ(ImageReadProblem(dir_ / "image_0" / "000002.png"), "not a decodable image");
  EXPECT_EQ(ImageReadProblem(dir_ / "image_0" / "000003.png"), "No such file or directory");
  EXPECT_TRUE(ReadFrameGray(d, d.frames[3]).empty());
  const Trajectory raw =
      MatchRawPosesToFrames(d, ReadTrajectory(dir_ / "raw.txt"), 0.02, dir_ / "raw.txt");
  PipelineOptions options;
  options.skip_unreadable_frames = false;
  try {
    RunPipeline(d, raw, options);
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.expected(), "a readable image") << e.what();
    EXPECT_EQ(e.got(), "not a decodable image") << e.what();
  }
  std::filesystem::copy(dir_ / "image_0" / "000001.png", dir_ / "image_0" / "000002.png",
                        std::filesystem::copy_options::overwrite_existing);
  try {
    RunPipeline(d, raw, options);
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_NE(e.file().find("000003.png"), std::string::npos) << e.what();
    EXPECT_EQ(e.got(), "No such file or directory") << e.what();
  }
}

TEST_F(BadSequence, PoseFileShorterThanImageList) {
  std::ofstream(dir_ / "short.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0.5 0 1 0 0 0 0 1 0\n";
  const Dataset d = OpenDataset("kitti:" + dir_.string());
  try {
    MatchRawPosesToFrames(d, ReadTrajectory(dir_ / "short.txt"), 0.02, dir_ / "short.txt");
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("short.txt"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("6 images"), std::string::npos) << e.what();
  }
}

// ------------------------------------------------------------------------- images of a dataset

// Images that ORB cannot use, or that would make the decoder abort, are refused by name when the
// dataset is opened, before any frame is processed (OpenDataset, dataset.h).
class BadImages : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::TempDir() / "images";
    std::filesystem::create_directories(dir_);
    options_.intrinsics_name = "--intrinsics";
    CameraIntrinsics k;
    k.fx = k.fy = 50;
    k.cx = 32;
    k.cy = 24;
    options_.intrinsics = k;
  }
  std::filesystem::path Write(const std::string& name, const cv::Mat& image) {
    const auto path = dir_ / name;
    EXPECT_TRUE(cv::imwrite(path.string(), image));
    return path;
  }
  // Expects OpenDataset to throw a FileError naming `file` whose message contains `message`.
  void ExpectRefused(const std::filesystem::path& file, const std::string& message) {
    try {
      OpenDataset("images:" + dir_.string(), options_);
      ADD_FAILURE() << "accepted; expected: " << message;
    } catch (const FileError& e) {
      EXPECT_EQ(e.file(), file.string()) << e.what();
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
  static cv::Mat Textured(int width, int height) {
    cv::Mat image;
    cv::resize(TexturedImage(7), image, cv::Size(width, height));
    return image;
  }
  std::filesystem::path dir_;
  DatasetOptions options_;
};

TEST_F(BadImages, TinyImageIsRefusedNamingTheFile) {
  Write("0.png", Textured(64, 48));
  const auto tiny = Write("1.png", cv::Mat(1, 1, CV_8UC1, cv::Scalar(9)));
  ExpectRefused(tiny, "at least 32x32 pixels");
  std::filesystem::remove(tiny);
  EXPECT_EQ(OpenDataset("images:" + dir_.string(), options_).frames.size(), 1u);
}

TEST_F(BadImages, HugePngHeaderIsRefusedBeforeDecoding) {
  Write("0.png", Textured(64, 48));
  const auto huge = dir_ / "1.png";
  test::WritePngHeader(huge, 100000, 100000);
  ExpectRefused(huge, "got 100000x100000");
}

TEST_F(BadImages, MixedSizesAreRefusedNamingTheFileAndTheSizeExpected) {
  const auto first = Write("0.png", Textured(64, 48));
  Write("1.jpg", Textured(64, 48));
  const auto other = Write("2.pgm", Textured(80, 60));
  ExpectRefused(other, "64x48 (the size of " + first.string() + "), got 80x60");
  // Against the intrinsics' own size when they have one.
  options_.intrinsics->width = 80;
  options_.intrinsics->height = 60;
  ExpectRefused(first, "80x60 (the size of --intrinsics), got 64x48");
}

TEST_F(BadImages, SizeComesFromTheFirstImageOfAnyFormat) {
  Write("0.jpg", Textured(64, 48));
  Write("1.bmp", Textured(64, 48));
  const Dataset d = OpenDataset("images:" + dir_.string(), options_);
  EXPECT_EQ(d.intrinsics.width, 64);
  EXPECT_EQ(d.intrinsics.height, 48);
  EXPECT_EQ(d.intrinsics_source, "--intrinsics");
}

TEST_F(BadImages, PrincipalPointOutsideTheImageNamesTheIntrinsics) {
  Write("0.png", Textured(64, 48));
  options_.intrinsics->cx = 500;
  try {
    OpenDataset("images:" + dir_.string(), options_);
    ADD_FAILURE() << "accepted a principal point outside the image";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--intrinsics: principal point (500, 24) outside the "
                                         "64x48 image (the size of " +
                                         (dir_ / "0.png").string() + ")"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(BadImages, TruncatedJpegIsRefusedNamingTheFile) {
  std::vector<uchar> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", Textured(640, 480), bytes));
  ASSERT_EQ(bytes[bytes.size() - 2], 0xFF);
  ASSERT_EQ(bytes.back(), 0xD9);
  options_.intrinsics->cx = 320;
  options_.intrinsics->cy = 240;
  std::ofstream(dir_ / "0.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  // Trailing NUL padding after the EOI marker is allowed.
  std::ofstream(dir_ / "1.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size())
      .write("\0\0\0", 3);
  EXPECT_EQ(OpenDataset("images:" + dir_.string(), options_).frames.size(), 2u);
  std::ofstream(dir_ / "2.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size() / 2);
  ExpectRefused(dir_ / "2.jpg", "a truncated file");
}

// The same checks hold for every kind of dataset: a 1x1 image inside a KITTI sequence.
TEST_F(BadSequence, TinyImageInAKittiSequenceIsRefusedNamingIt) {
  const auto tiny = dir_ / "image_0" / "000003.png";
  ASSERT_TRUE(cv::imwrite(tiny.string(), cv::Mat(1, 1, CV_8UC1, cv::Scalar(0))));
  try {
    OpenDataset("kitti:" + dir_.string());
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), tiny.string()) << e.what();
  }
}

// ------------------------------------------------------------------------------------ g2o files

// Expects ReadG2o(text) to throw a FileError at `line` whose message contains `message`.
void ExpectG2oError(const std::string& text, int line, const std::string& message) {
  std::istringstream in(text);
  try {
    ReadG2o(in, "graph.g2o");
    ADD_FAILURE() << "accepted:\n" << text;
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), "graph.g2o");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
  }
}

const char* kSe2Info = " 1 0 0 1 0 1";  // identity, upper triangle

TEST(BadG2o, EdgeToAnUndefinedVertexWhenTheFileHasVertices) {
  const std::string vertices = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n";
  const std::string edge01 = std::string("EDGE_SE2 0 1 1 0 0") + kSe2Info + "\n";
  const std::string edge12 = std::string("EDGE_SE2 1 2 1 0 0") + kSe2Info + "\n";
  ExpectG2oError(vertices + edge01 + edge12, 4, "vertex 2 is not defined");
  // An edges-only file still chains its vertices from the lowest id (docs/POSEGRAPH.md).
  std::istringstream edges_only(edge01 + edge12);
  const PoseGraph graph = ReadG2o(edges_only, "edges.g2o");
  EXPECT_EQ(graph.num_vertices(), 3u);
  // FIX of an unknown vertex names its line.
  ExpectG2oError(vertices + edge01 + "FIX 7\n", 4, "FIX of a known vertex");
}

TEST(BadG2o, ZeroOrIndefiniteInformationNamesTheLine) {
  const std::string vertices = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n";
  ExpectG2oError(vertices + "EDGE_SE2 0 1 1 0 0 0 0 0 0 0 0\n", 3, "all zeros");
  ExpectG2oError(vertices + "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 0\n", 3, "positive-definite");
  ExpectG2oError(vertices + "EDGE_SE2 0 1 1 0 0 1 2 0 1 0 1\n", 3, "smallest eigenvalue -1");
  const std::string se3 =
      "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n"
      "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1";
  std::string zeros, indefinite;  // 21 upper-triangular entries
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) {
      zeros += " 0";
      indefinite += r != c ? " 0" : (r == 5 ? " -1" : " 1");  // identity but one -1
    }
  }
  ExpectG2oError(se3 + zeros + "\n", 3, "all zeros");
  ExpectG2oError(se3 + indefinite + "\n", 3, "positive-definite");
}

}  // namespace
}  // namespace sparseloop
