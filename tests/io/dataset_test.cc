#include "sparseloop/io/dataset.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/trajectory_io.h"
#include "test_util.h"

namespace sparseloop {
namespace {

namespace fs = std::filesystem;

// Expects FileError naming `file` (and `line` when >= 0).
#define EXPECT_FILE_ERROR(statement, want_file, want_line)                 \
  do {                                                                     \
    try {                                                                  \
      statement;                                                           \
      ADD_FAILURE() << "no FileError from " #statement;                    \
    } catch (const FileError& sl_error) {                                  \
      EXPECT_EQ(sl_error.file(), (want_file).string()) << sl_error.what(); \
      if ((want_line) >= 0) {                                              \
        EXPECT_EQ(sl_error.line(), (want_line)) << sl_error.what();        \
      }                                                                    \
    }                                                                      \
  } while (false)

// ----------------------------------------------------------------------------------------- PNG

TEST(PngSize, ReadsIhdrAndRejectsOtherFiles) {
  const auto dir = test::TempDir();
  test::WritePngHeader(dir / "a.png", 1226, 370);
  const ImageSize s = ReadPngSize(dir / "a.png");
  EXPECT_EQ(s.width, 1226);
  EXPECT_EQ(s.height, 370);
  test::WriteText(dir / "b.png", "not a png at all, but long enough to read");
  EXPECT_FILE_ERROR(ReadPngSize(dir / "b.png"), dir / "b.png", 0);
  EXPECT_FILE_ERROR(ReadPngSize(dir / "c.png"), dir / "c.png", 0);
}

TEST(ImageSize, PngJpegPnmBmpHeadersAndUnknownFiles) {
  const auto dir = test::TempDir();
  test::WritePngHeader(dir / "a.png", 1226, 370);
  // JPEG: SOI, an APP0 segment to skip, then SOF0 (precision 8, height 48, width 64).
  test::WriteText(dir / "b.jpg", std::string("\xFF\xD8\xFF\xE0\x00\x04\x00\x00", 8) +
                                     std::string("\xFF\xC0\x00\x0B\x08\x00\x30\x00\x40", 9));
  test::WriteText(dir / "c.pgm", "P5\n# a comment\n 320 240\n255\n");
  std::string bmp = "BM" + std::string(24, '\0');
  bmp[14] = 40;    // BITMAPINFOHEADER
  bmp[18] = 0x40;  // width 64
  bmp[22] = static_cast<char>(0xD0), bmp[23] = bmp[24] = bmp[25] = static_cast<char>(0xFF);  // -48
  test::WriteText(dir / "d.bmp", bmp);
  const std::pair<const char*, ImageSize> known[] = {
      {"a.png", {1226, 370}}, {"b.jpg", {64, 48}}, {"c.pgm", {320, 240}}, {"d.bmp", {64, 48}}};
  for (const auto& [name, size] : known) {
    const auto got = ReadImageSize(dir / name);
    ASSERT_TRUE(got.has_value()) << name;
    EXPECT_EQ(got->width, size.width) << name;
    EXPECT_EQ(got->height, size.height) << name;
  }
  test::WriteText(dir / "e.jpg", std::string("\xFF\xD8\xFF\xE0\x00", 5));  // cut short
  test::WriteText(dir / "f.png", "not an image");
  for (const char* name : {"e.jpg", "f.png", "missing.png"}) {
    EXPECT_FALSE(ReadImageSize(dir / name).has_value()) << name;
  }
}

// --------------------------------------------------------------------------------------- specs

TEST(OpenDataset, BadSpecsAndOptions) {
  EXPECT_THROW(OpenDataset("kitti"), std::invalid_argument);
  EXPECT_THROW(OpenDataset("kitti:"), std::invalid_argument);
  EXPECT_THROW(OpenDataset("colmap:/tmp"), std::invalid_argument);
  DatasetOptions bad;
  bad.tum_max_dt = 0.0;
  EXPECT_THROW(OpenDataset("kitti:/tmp", bad), std::invalid_argument);
  const auto missing = test::TempDir() / "none";
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + missing.string()), missing, 0);
}

// --------------------------------------------------------------------------------------- KITTI

// A 3-frame KITTI folder: image_0/00000{0,1,2}.png, times.txt, calib.txt, poses.txt.
fs::path MakeKittiFolder(const fs::path& dir, int poses = 3, int times = 3) {
  for (int i = 0; i < 3; ++i) {
    test::WritePngHeader(dir / "image_0" / fmt::format("{:06d}.png", i), 640, 200);
  }
  std::string t, p;
  for (int i = 0; i < times; ++i) t += fmt::format("{:e}\n", 0.1 * i + 0.05);
  for (int i = 0; i < poses; ++i) p += fmt::format("1 0 0 {} 0 1 0 0 0 0 1 {}\n", i, 2 * i);
  test::WriteText(dir / "times.txt", t);
  test::WriteText(dir / "poses.txt", p);
  test::WriteText(dir / "calib.txt",
                  "P0: 500.5 0 320.25 0 0 501.5 99.75 0 0 0 1 0\n"
                  "P1: 500.5 0 320.25 -200 0 501.5 99.75 0 0 0 1 0\n");
  return dir;
}

TEST(OpenDatasetKitti, SyntheticFolder) {
  const auto dir = MakeKittiFolder(test::TempDir());
  const Dataset d = OpenDataset("kitti:" + dir.string());
  EXPECT_EQ(d.kind, "kitti");
  ASSERT_EQ(d.frames.size(), 3u);
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 500.5);
  EXPECT_DOUBLE_EQ(d.intrinsics.fy, 501.5);
  EXPECT_DOUBLE_EQ(d.intrinsics.cx, 320.25);
  EXPECT_DOUBLE_EQ(d.intrinsics.cy, 99.75);
  EXPECT_EQ(d.intrinsics.width, 640);
  EXPECT_EQ(d.intrinsics.height, 200);
  EXPECT_EQ(d.intrinsics.distortion_model, DistortionModel::kNone);
  EXPECT_DOUBLE_EQ(d.frames[2].timestamp, 0.25);
  EXPECT_EQ(d.frames[2].image_path, dir / "image_0" / "000002.png");
  EXPECT_EQ(d.gt_path, dir / "poses.txt");
  ASSERT_TRUE(d.has_gt());
  EXPECT_EQ(d.frames[2].gt_world_from_cam->translation, Eigen::Vector3d(2, 0, 4));
  const Trajectory gt = d.GtTrajectory();
  ASSERT_EQ(gt.size(), 3u);
  EXPECT_DOUBLE_EQ(gt.poses[1].timestamp, 0.15);
}

TEST(OpenDatasetKitti, ShortPoseFileIsFileError) {
  const auto dir = MakeKittiFolder(test::TempDir(), /*poses=*/2);
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + dir.string()), dir / "poses.txt", 0);
}

TEST(OpenDatasetKitti, ShortTimesIsFileError) {
  const auto dir = MakeKittiFolder(test::TempDir(), 3, /*times=*/2);
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + dir.string()), dir / "times.txt", 0);
}

TEST(OpenDatasetKitti, MalformedCalibAndGapsAreFileErrors) {
  const auto dir = MakeKittiFolder(test::TempDir());
  test::WriteText(dir / "calib.txt", "P0: 500 0 320 0 0 500 100 0 0 0 1\n");
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + dir.string()), dir / "calib.txt", 1);
  test::WriteText(dir / "calib.txt", "P1: 500 0 320 0 0 500 100 0 0 0 1 0\n");
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + dir.string()), dir / "calib.txt", 0);
  fs::remove(dir / "calib.txt");
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + dir.string()), dir / "calib.txt", 0);
  MakeKittiFolder(dir);
  fs::rename(dir / "image_0" / "000001.png", dir / "image_0" / "000007.png");
  EXPECT_FILE_ERROR(OpenDataset("kitti:" + dir.string()), dir / "image_0" / "000002.png", 0);
}

TEST(OpenDatasetKitti, PoseFileDiscoveryAndOverride) {
  const auto dir = MakeKittiFolder(test::TempDir());
  fs::remove(dir / "poses.txt");
  // No poses.txt / <dir>.txt: the first *.txt with 12 columns and exactly 3 rows is taken.
  test::WriteText(dir / "a_long.txt", std::string(5, '\n') + "1 0 0 0 0 1 0 0 0 0 1 0\n" +
                                          "1 0 0 1 0 1 0 0 0 0 1 0\n1 0 0 2 0 1 0 0 0 0 1 0\n" +
                                          "1 0 0 3 0 1 0 0 0 0 1 0\n");
  test::WriteText(dir / "b_gt.txt",
                  "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 5 0 1 0 0 0 0 1 0\n"
                  "1 0 0 6 0 1 0 0 0 0 1 0\n");
  Dataset d = OpenDataset("kitti:" + dir.string());
  EXPECT_EQ(d.gt_path, dir / "b_gt.txt");
  EXPECT_EQ(d.frames[1].gt_world_from_cam->translation.x(), 5.0);
  // Nothing matching: no GT, not an error.
  fs::remove(dir / "b_gt.txt");
  d = OpenDataset("kitti:" + dir.string());
  EXPECT_FALSE(d.has_gt());
  EXPECT_TRUE(d.gt_path.empty());
  // The option wins; extra poses beyond the images are ignored.
  DatasetOptions options;
  options.poses = dir / "a_long.txt";
  d = OpenDataset("kitti:" + dir.string(), options);
  EXPECT_EQ(d.frames[2].gt_world_from_cam->translation.x(), 2.0);
  // Options intrinsics override calib.txt.
  CameraIntrinsics k;
  k.fx = k.fy = 100;
  k.cx = 50;
  k.cy = 40;
  options.intrinsics = k;
  d = OpenDataset("kitti:" + dir.string(), options);
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 100.0);
}

TEST(OpenDatasetKitti, SequenceNamedPoseFileAndTrailingSlash) {
  const auto dir = MakeKittiFolder(test::TempDir() / "07");
  fs::rename(dir / "poses.txt", dir / "07.txt");
  const Dataset d = OpenDataset("kitti:" + dir.string() + "/");
  EXPECT_EQ(d.gt_path, dir / "07.txt");
  EXPECT_EQ(d.root, dir);
  EXPECT_EQ(d.GtTrajectory().size(), 3u);
}

TEST(OpenDatasetKitti, RealKitti07First160) {
  SL_REQUIRE_DATA("kitti07_first160");
  const auto dir = test::DataDir() / "kitti07_first160";
  const Dataset d = OpenDataset("kitti:" + dir.string());
  ASSERT_EQ(d.frames.size(), 160u);
  // calib.txt P0: 7.070912e+02 0 6.018873e+02 0 0 7.070912e+02 1.831104e+02 0 ...
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 707.0912);
  EXPECT_DOUBLE_EQ(d.intrinsics.fy, 707.0912);
  EXPECT_DOUBLE_EQ(d.intrinsics.cx, 601.8873);
  EXPECT_DOUBLE_EQ(d.intrinsics.cy, 183.1104);
  EXPECT_EQ(d.intrinsics.width, 1226);
  EXPECT_EQ(d.intrinsics.height, 370);
  EXPECT_NO_THROW(d.intrinsics.Check());
  // times.txt line 2: 1.038752e-01
  EXPECT_DOUBLE_EQ(d.frames[1].timestamp, 1.038752e-01);
  EXPECT_EQ(d.frames[159].image_path.filename(), "000159.png");
  EXPECT_TRUE(fs::exists(d.frames[159].image_path));
  EXPECT_EQ(d.gt_path.filename(), "07_first160_DERIVED.txt");
  const Trajectory gt = d.GtTrajectory();
  ASSERT_EQ(gt.size(), 160u);
  // Line 3 of the GT file: t = (-1.001116e-02, -4.359704e-03, 1.857373e-01).
  EXPECT_TRUE(d.frames[2].gt_world_from_cam->translation.isApprox(
      Eigen::Vector3d(-1.001116e-02, -4.359704e-03, 1.857373e-01), 1e-12));
  // The full 07.txt also works when given explicitly (first 160 rows used).
  DatasetOptions options;
  options.poses = dir / "07.txt";
  const Dataset full = OpenDataset("kitti:" + dir.string(), options);
  EXPECT_TRUE(full.frames[159].gt_world_from_cam->translation.isApprox(
      d.frames[159].gt_world_from_cam->translation, 1e-12));
}

// ----------------------------------------------------------------------------------------- TUM

TEST(OpenDatasetTum, AssociatesGroundTruthWithinMaxDt) {
  const auto dir = test::TempDir() / "rgbd_dataset_freiburg1_desk";
  test::WriteText(dir / "rgb.txt",
                  "# color images\n# file: 'x.bag'\n# timestamp filename\n"
                  "100.000 rgb/100.000.png\n100.100 rgb/100.100.png\n100.200 rgb/100.200.png\n");
  test::WriteText(dir / "groundtruth.txt",
                  "# timestamp tx ty tz qx qy qz qw\n"
                  "99.990 1 0 0 0 0 0 1\n100.005 2 0 0 0 0 0 1\n"  // nearest to 100.000: 100.005
                  "100.140 3 0 0 0 0 0 1\n"                        // 100.100 is 0.04 away: none
                  "100.195 4 0 0 0 0 0 1\n100.230 5 0 0 0 0 0 1\n");
  const Dataset d = OpenDataset("tum:" + dir.string());
  ASSERT_EQ(d.frames.size(), 3u);
  EXPECT_EQ(d.frames[1].image_path, dir / "rgb/100.100.png");
  ASSERT_TRUE(d.frames[0].gt_world_from_cam);
  EXPECT_EQ(d.frames[0].gt_world_from_cam->translation.x(), 2.0);
  EXPECT_FALSE(d.frames[1].gt_world_from_cam);
  ASSERT_TRUE(d.frames[2].gt_world_from_cam);
  EXPECT_EQ(d.frames[2].gt_world_from_cam->translation.x(), 4.0);
  // freiburg1 intrinsics from the folder name.
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 517.3);
  EXPECT_EQ(d.intrinsics.distortion.size(), 5u);
  // A wider window associates frame 1 too.
  DatasetOptions wide;
  wide.tum_max_dt = 0.05;
  EXPECT_EQ(OpenDataset("tum:" + dir.string(), wide).GtTrajectory().size(), 3u);
}

TEST(OpenDatasetTum, IntrinsicsNeededWithoutFreiburgNameAndBadRgbLines) {
  const auto dir = test::TempDir() / "my_sequence";
  test::WriteText(dir / "rgb.txt", "1.0 rgb/1.png\n2.0 rgb/2.png\n");
  EXPECT_THROW(OpenDataset("tum:" + dir.string()), std::invalid_argument);
  DatasetOptions options;
  options.intrinsics = TumFreiburgIntrinsics(3);
  const Dataset d = OpenDataset("tum:" + dir.string(), options);
  EXPECT_FALSE(d.has_gt());
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 535.4);
  test::WriteText(dir / "rgb.txt", "1.0 rgb/1.png\n1.0 rgb/2.png\n");
  EXPECT_FILE_ERROR(OpenDataset("tum:" + dir.string(), options), dir / "rgb.txt", 2);
  test::WriteText(dir / "rgb.txt", "1.0\n");
  EXPECT_FILE_ERROR(OpenDataset("tum:" + dir.string(), options), dir / "rgb.txt", 1);
  EXPECT_THROW(TumFreiburgIntrinsics(4), std::invalid_argument);
}

// --------------------------------------------------------------------------------------- EuRoC

const char kSensorYaml[] = R"(%YAML:1.0
camera_id: cam0
T_BS:
  cols: 4
  rows: 4
  data: [0.0, -1.0, 0.0, 0.5,
         1.0, 0.0, 0.0, 0.0,
         0.0, 0.0, 1.0, 0.0,   # a comment inside the list
         0.0, 0.0, 0.0, 1.0]
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
)";

fs::path MakeEurocFolder(const fs::path& dir) {
  const auto cam = dir / "mav0" / "cam0";
  test::WriteText(cam / "data.csv",
                  "#timestamp [ns],filename\n"
                  "1403636579763555584,1403636579763555584.png\n"
                  "1403636579813555456,1403636579813555456.png\n");
  test::WriteText(cam / "sensor.yaml", kSensorYaml);
  test::WriteText(dir / "mav0" / "state_groundtruth_estimate0" / "data.csv",
                  "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
                  "q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1]\n"
                  "1403636579763555000,1,2,3,1,0,0,0,0.5\n"
                  "1403636579900000000,4,5,6,1,0,0,0,0.5\n");
  return dir;
}

TEST(OpenDatasetEuroc, SyntheticFolderWithBodyToCameraGt) {
  const auto dir = MakeEurocFolder(test::TempDir());
  const Dataset d = OpenDataset("euroc:" + dir.string());
  ASSERT_EQ(d.frames.size(), 2u);
  EXPECT_EQ(d.frames[0].image_path, dir / "mav0/cam0/data/1403636579763555584.png");
  EXPECT_NEAR(d.frames[1].timestamp, 1403636579.813555456, 1e-6);
  EXPECT_DOUBLE_EQ(d.intrinsics.fx, 458.654);
  EXPECT_EQ(d.intrinsics.width, 752);
  EXPECT_EQ(d.intrinsics.distortion_model, DistortionModel::kRadialTangential);
  ASSERT_EQ(d.intrinsics.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(d.intrinsics.distortion[3], 1.76187114e-05);
  // Frame 0 is 0.58 us from the first GT row; frame 1 is 86 ms from any row (> 5 ms).
  ASSERT_TRUE(d.frames[0].gt_world_from_cam);
  EXPECT_FALSE(d.frames[1].gt_world_from_cam);
  // world_from_cam = world_from_body (identity rotation, t=(1,2,3)) * T_BS (t=(0.5,0,0)).
  EXPECT_TRUE(d.frames[0].gt_world_from_cam->translation.isApprox(Eigen::Vector3d(1.5, 2, 3)));
  EXPECT_TRUE((d.frames[0].gt_world_from_cam->rotation * Eigen::Vector3d::UnitX())
                  .isApprox(Eigen::Vector3d::UnitY()));
  DatasetOptions body;
  body.euroc_gt_in_camera_frame = false;
  const Dataset b = OpenDataset("euroc:" + dir.string(), body);
  EXPECT_EQ(b.frames[0].gt_world_from_cam->translation, Eigen::Vector3d(1, 2, 3));
}

// kSensorYaml with `from` replaced by `to`, written as dir/name.
fs::path EditedSensorYaml(const fs::path& dir, const std::string& name, const std::string& from,
                          const std::string& to) {
  std::string yaml = kSensorYaml;
  yaml.replace(yaml.find(from), from.size(), to);
  return test::WriteText(dir / name, yaml);
}

// The message of the FileError `read` throws ("" when none).
template <typename Read>
std::string FileErrorOf(Read&& read) {
  try {
    read();
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

TEST(EurocSensorYaml, MalformedFilesNameTheLine) {
  const auto dir = test::TempDir();
  struct Case {
    const char* from;
    const char* to;
    int line;
  };
  const Case cases[] = {
      // Unclosed list: reported at the line of its key.
      {"0.0, 0.0, 0.0, 1.0]", "0.0, 0.0, 0.0, 1.0", 6},
      {"[458.654, 457.296, 367.215, 248.375]", "[458.654, 457.296, 367.215]", 13},
      {"radial-tangential", "fisheye", 14},
      {"0.0, -1.0, 0.0, 0.5", "0.0, -2.0, 0.0, 0.5", 6},
      {"0.07395907", "0.07x", 15},
  };
  int k = 0;
  for (const Case& c : cases) {
    const fs::path path = EditedSensorYaml(dir, std::to_string(k++) + ".yaml", c.from, c.to);
    EXPECT_FILE_ERROR(ReadEurocSensorYaml(path), path, c.line);
  }
}

// A distortion sparseloop cannot use as written is refused naming the key's line: a coefficient
// beyond any lens (1e10), or non-zero coefficients without a distortion_model (they were
// ignored). All-zero coefficients without a model are no distortion.
TEST(EurocSensorYaml, DistortionIsCheckedNamingTheKey) {
  const auto dir = test::TempDir();
  const fs::path huge = EditedSensorYaml(dir, "a.yaml", "-0.28340811", "1e10");
  EXPECT_FILE_ERROR(ReadEurocSensorYaml(huge), huge, 15);
  EXPECT_NE(FileErrorOf([&] { ReadEurocSensorYaml(huge); }).find("distortion_coefficients"),
            std::string::npos);
  const fs::path no_model =
      EditedSensorYaml(dir, "b.yaml", "distortion_model: radial-tangential", "rate: 1");
  EXPECT_FILE_ERROR(ReadEurocSensorYaml(no_model), no_model, 15);
  EXPECT_NE(FileErrorOf([&] { ReadEurocSensorYaml(no_model); }).find("no distortion_model"),
            std::string::npos);
  const fs::path none = EditedSensorYaml(dir, "c.yaml", "radial-tangential", "none");
  EXPECT_FILE_ERROR(ReadEurocSensorYaml(none), none, 15);
  std::string zeros = test::ReadText(none);
  zeros.replace(zeros.find("[-0.28340811"), 53, "[0, 0, 0, 0]");
  test::WriteText(dir / "d.yaml", zeros);
  EXPECT_EQ(ReadEurocSensorYaml(dir / "d.yaml").intrinsics.distortion_model,
            DistortionModel::kNone);
}

TEST(EurocSensorYaml, RealSensorLeft) {
  SL_REQUIRE_DATA("euroc_loop_pairs");
  const auto info = ReadEurocSensorYaml(test::DataDir() / "euroc_loop_pairs/sensorLeft.yaml");
  EXPECT_DOUBLE_EQ(info.intrinsics.fx, 458.654);
  EXPECT_DOUBLE_EQ(info.intrinsics.fy, 457.296);
  EXPECT_DOUBLE_EQ(info.intrinsics.cx, 367.215);
  EXPECT_DOUBLE_EQ(info.intrinsics.cy, 248.375);
  EXPECT_EQ(info.intrinsics.width, 752);
  EXPECT_EQ(info.intrinsics.height, 480);
  EXPECT_EQ(info.intrinsics.distortion_model, DistortionModel::kRadialTangential);
  EXPECT_EQ(info.intrinsics.distortion,
            (std::vector<double>{-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05}));
  ASSERT_TRUE(info.body_from_cam);
  EXPECT_TRUE(info.body_from_cam->translation.isApprox(
      Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949), 1e-12));
  EXPECT_NEAR(info.body_from_cam->RotationMatrix()(0, 1), -0.999880929698, 1e-6);
}

// -------------------------------------------------------------------------------------- images

TEST(OpenDatasetImages, NaturalOrderIntrinsicsAndPosesByIndex) {
  const auto dir = test::TempDir();
  for (const char* name : {"10.png", "2.png", "1.png"}) test::WritePngHeader(dir / name, 64, 48);
  test::WriteText(dir / "notes.txt", "ignored");
  EXPECT_THROW(OpenDataset("images:" + dir.string()), std::invalid_argument);
  DatasetOptions options;
  CameraIntrinsics k;
  k.fx = k.fy = 50;
  k.cx = 32;
  k.cy = 24;
  options.intrinsics = k;
  const auto poses = test::WriteText(dir.parent_path() / (dir.filename().string() + "_p.txt"),
                                     "0 1 0 0 0 0 1 0 0 0 0 1 0\n2 1 0 0 7 0 1 0 0 0 0 1 0\n");
  options.poses = poses;
  const Dataset d = OpenDataset("images:" + dir.string(), options);
  ASSERT_EQ(d.frames.size(), 3u);
  EXPECT_EQ(d.frames[0].image_path.filename(), "1.png");
  EXPECT_EQ(d.frames[1].image_path.filename(), "2.png");
  EXPECT_EQ(d.frames[2].image_path.filename(), "10.png");
  EXPECT_DOUBLE_EQ(d.frames[2].timestamp, 2.0);
  EXPECT_EQ(d.intrinsics.width, 64);  // filled from the PNG header
  EXPECT_TRUE(d.frames[0].gt_world_from_cam);
  EXPECT_FALSE(d.frames[1].gt_world_from_cam);
  EXPECT_EQ(d.frames[2].gt_world_from_cam->translation.x(), 7.0);
  const auto empty = test::TempDir() / "empty";
  fs::create_directories(empty);
  EXPECT_FILE_ERROR(OpenDataset("images:" + empty.string(), options), empty, 0);
}

}  // namespace
}  // namespace sparseloop
