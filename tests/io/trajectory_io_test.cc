#include "sparseloop/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/quaternion.h"
#include "test_util.h"

namespace sparseloop {
namespace {

using F = TrajectoryFormat;

TEST(TrajectoryFormatName, ParsesEveryNameAndRejectsOthers) {
  EXPECT_EQ(ParseTrajectoryFormat("auto"), F::kAuto);
  EXPECT_EQ(ParseTrajectoryFormat("tum"), F::kTum);
  EXPECT_EQ(ParseTrajectoryFormat("kitti"), F::kKitti);
  EXPECT_EQ(ParseTrajectoryFormat("euroc"), F::kEuroc);
  EXPECT_EQ(ParseTrajectoryFormat("positions"), F::kPositions);
  for (F f : {F::kAuto, F::kTum, F::kKitti, F::kEuroc, F::kPositions}) {
    EXPECT_EQ(ParseTrajectoryFormat(ToString(f)), f);
  }
  EXPECT_THROW(ParseTrajectoryFormat("TUM"), std::invalid_argument);
  EXPECT_THROW(ParseTrajectoryFormat(""), std::invalid_argument);
}

// ------------------------------------------------------------------------ malformed input table

struct MalformedCase {
  const char* name;
  F format;
  const char* content;
  int line;              // expected FileError::line() (0 = whole file)
  const char* expected;  // substring of FileError::expected()
};

const char kTumOk[] = "1.0 0 0 0 0 0 0 1\n";
const char kKittiOk[] = "1 0 0 0 0 1 0 0 0 0 1 0\n";

const MalformedCase kMalformed[] = {
    // empty files
    {"empty", F::kAuto, "", 0, "at least one data line"},
    {"comments_only", F::kTum, "# nothing\n\n   \n", 0, "at least one data line"},
    {"empty_kitti", F::kKitti, "\n", 0, "at least one data line"},
    {"empty_euroc", F::kEuroc, "#timestamp [ns],x\n", 0, "at least one data line"},
    {"empty_positions", F::kPositions, "", 0, "at least one data line"},
    // TUM
    {"tum_columns", F::kTum, "# c\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", 3, "8 columns"},
    {"tum_number", F::kTum, "1.0 0 0 0 0 0 0 1\n2.0 0 0 0x1 0 0 0 1\n", 2, "finite number"},
    {"tum_word", F::kTum, "1.0 0 0 abc 0 0 0 1\n", 1, "finite number for z"},
    {"tum_nan", F::kTum, "1.0 0 nan 0 0 0 0 1\n", 1, "finite number for y"},
    {"tum_inf", F::kTum, "inf 0 0 0 0 0 0 1\n", 1, "finite number for timestamp"},
    {"tum_overflow", F::kTum, "1.0 1e999 0 0 0 0 0 1\n", 1, "finite number for x"},
    {"tum_quat_norm", F::kTum, "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1.01\n", 2, "unit quaternion"},
    {"tum_quat_zero", F::kTum, "1.0 0 0 0 0 0 0 0\n", 1, "unit quaternion"},
    {"tum_duplicate_time", F::kTum, "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n", 2,
     "timestamp greater"},
    {"tum_decreasing_time", F::kTum, "2.0 0 0 0 0 0 0 1\n\n1.5 0 0 0 0 0 0 1\n", 3,
     "timestamp greater"},
    // KITTI
    {"kitti_columns", F::kKitti, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n", 2,
     "12 columns"},
    {"kitti_first_columns", F::kKitti, "1 0 0 0 0 1 0 0 0 0 1\n", 1, "12 columns"},
    {"kitti_number", F::kKitti, "1 0 0 0 0 1 0 0 0 0 1 zz\n", 1, "finite number"},
    {"kitti_nan", F::kKitti, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 NaN 0 1 0 0 0 0 1 0\n", 2,
     "finite number"},
    {"kitti_scaled", F::kKitti, "1.1 0 0 0 0 1.1 0 0 0 0 1.1 0\n", 1, "rotation"},
    {"kitti_reflection", F::kKitti, "-1 0 0 0 0 1 0 0 0 0 1 0\n", 1, "rotation"},
    {"kitti_shear", F::kKitti, "1 0.01 0 0 0 1 0 0 0 0 1 0\n", 1, "rotation"},
    {"kitti_frame_not_int", F::kKitti, "2.5 1 0 0 0 0 1 0 0 0 0 1 0\n", 1, "integer"},
    {"kitti_frame_duplicate", F::kKitti,
     "2 1 0 0 0 0 1 0 0 0 0 1 0\n3 1 0 0 0 0 1 0 0 0 0 1 0\n3 1 0 0 0 0 1 0 0 0 0 1 0\n", 3,
     "frame index greater"},
    {"kitti_frame_decreasing", F::kKitti, "5 1 0 0 0 0 1 0 0 0 0 1 0\n4 1 0 0 0 0 1 0 0 0 0 1 0\n",
     2, "frame index greater"},
    // EuRoC
    {"euroc_columns", F::kEuroc, "#h\n100,0,0,0,1,0,0\n", 2, ">= 8"},
    {"euroc_ragged", F::kEuroc, "100,0,0,0,1,0,0,0\n200,0,0,0,1,0,0,0,5\n", 2, "8 columns"},
    {"euroc_time_float", F::kEuroc, "1.5e9,0,0,0,1,0,0,0\n", 1, "integer"},
    {"euroc_number", F::kEuroc, "100,0,0,0,1,0,0,0\n200,0,,0,1,0,0,0\n", 2, "finite number"},
    {"euroc_extra_nan", F::kEuroc, "100,0,0,0,1,0,0,0,nan\n", 1, "column 9"},
    {"euroc_quat", F::kEuroc, "100,0,0,0,0.5,0,0,0\n", 1, "unit quaternion"},
    {"euroc_duplicate", F::kEuroc, "100,0,0,0,1,0,0,0\n100,0,0,0,1,0,0,0\n", 2,
     "timestamp greater"},
    // positions
    {"positions_columns", F::kPositions, "0 1 2 3\n1 1 2\n", 2, "4 columns"},
    {"positions_first_columns", F::kPositions, "0 1 2\n", 1, ">= 4 columns"},
    {"positions_frame", F::kPositions, "0 1 2 3\n1.5 1 2 3\n", 2, "integer"},
    {"positions_inf", F::kPositions, "0 1 2 3 -inf\n", 1, "column 5"},
    {"positions_order", F::kPositions, "0 1 2 3\n2 1 2 3\n1 1 2 3\n", 3, "frame index greater"},
    // positions beyond kMaxCoordinate (a file scaled by 1e200: sums of squares overflow)
    {"tum_huge_x", F::kTum, "1.0 0 0 0 0 0 0 1\n2.0 1e200 0 0 0 0 0 1\n", 2,
     "coordinate within +-1e+15 for x"},
    {"kitti_huge_t", F::kKitti, "1 0 0 0 0 1 0 0 0 0 1 -2e16\n", 1,
     "coordinate within +-1e+15 for matrix entry (2,3)"},
    {"euroc_huge_p", F::kEuroc, "100,0,1e30,0,1,0,0,0\n", 1, "coordinate within +-1e+15 for p_y"},
    {"positions_huge", F::kPositions, "0 1 2 3\n1 1 2 -1e300\n", 2, "coordinate within"},
    // auto-detection failure
    {"auto_two_columns", F::kAuto, "# c\n1.0 2.0\n", 2, "a trajectory line"},
    {"auto_words", F::kAuto, "time x y z\n", 1, "a trajectory line"},
};

TEST(TrajectoryRead, EveryMalformedInputIsFileErrorWithFileAndLine) {
  const auto dir = test::TempDir();
  for (const auto& c : kMalformed) {
    SCOPED_TRACE(c.name);
    const auto path = test::WriteText(dir / (std::string(c.name) + ".txt"), c.content);
    try {
      ReadTrajectory(path, c.format);
      ADD_FAILURE() << "no FileError";
    } catch (const FileError& e) {
      EXPECT_EQ(e.file(), path.string());
      EXPECT_EQ(e.line(), c.line) << e.what();
      const std::string prefix = c.line > 0
                                     ? path.string() + ":" + std::to_string(c.line) + ": expected "
                                     : path.string() + ": expected ";
      EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
      EXPECT_NE(e.expected().find(c.expected), std::string::npos) << e.what();
    }
  }
}

// Files as editors write them: a UTF-8 byte order mark before the first line, and lines ended by
// "\r\n" (Windows) or a lone "\r" (classic Mac OS) read as the "\n" file does, line numbers
// included.
TEST(TrajectoryRead, ByteOrderMarkAndEveryLineEndingReadTheSame) {
  const auto dir = test::TempDir();
  const std::string lines[] = {"# t x y z qx qy qz qw", "0 0 0 0 0 0 0 1", "1 1 0 0 0 0 0 1",
                               "2 2 0 0 0 0 0 1"};
  for (const std::string bom : {"", "\xEF\xBB\xBF"}) {
    for (const std::string end : {"\n", "\r\n", "\r"}) {
      SCOPED_TRACE("bom " + std::to_string(bom.size()) + ", end " + std::to_string(end.size()) +
                   (end == "\r" ? " CR" : ""));
      std::string text = bom;
      for (const auto& l : lines) text += l + end;
      const auto path = test::WriteText(dir / "t.txt", text);
      EXPECT_EQ(DetectTrajectoryFormat(path), F::kTum);
      const Trajectory t = ReadTrajectory(path);
      ASSERT_EQ(t.size(), 3u);
      EXPECT_DOUBLE_EQ(t.poses[2].world_from_cam.translation.x(), 2.0);
      // An error names the line an editor shows: the 4th.
      test::WriteText(
          path, bom + lines[0] + end + lines[1] + end + lines[2] + end + "2 2 0 0 0 0 0 1.5" + end);
      try {
        ReadTrajectory(path);
        ADD_FAILURE() << "no FileError";
      } catch (const FileError& e) {
        EXPECT_EQ(e.line(), 4) << e.what();
      }
    }
  }
  // KITTI and EuRoC too (one reader of lines for every format).
  const auto kitti = test::WriteText(dir / "k.txt",
                                     "\xEF\xBB\xBF"
                                     "1 0 0 0 0 1 0 0 0 0 1 0\r"
                                     "1 0 0 5 0 1 0 0 0 0 1 0\r");
  EXPECT_EQ(ReadTrajectory(kitti).size(), 2u);
  const auto euroc = test::WriteText(dir / "e.csv",
                                     "\xEF\xBB\xBF#t,x\r100,0,0,0,1,0,0,0\r"
                                     "200,1,0,0,1,0,0,0\r");
  EXPECT_EQ(ReadTrajectory(euroc).size(), 2u);
}

TEST(TrajectoryRead, MissingFileAndDirectoryAreFileErrors) {
  const auto dir = test::TempDir();
  for (F f : {F::kAuto, F::kTum, F::kKitti, F::kEuroc, F::kPositions}) {
    try {
      ReadTrajectory(dir / "missing.txt", f);
      ADD_FAILURE() << "no FileError";
    } catch (const FileError& e) {
      EXPECT_EQ(e.file(), (dir / "missing.txt").string());
      EXPECT_EQ(e.line(), 0);
      EXPECT_NE(e.expected().find("existing file"), std::string::npos);
    }
  }
  EXPECT_THROW(ReadTrajectory(dir), FileError);
}

TEST(TrajectoryRead, NearlyUnitQuaternionIsNormalised) {
  const auto path = test::WriteText(test::TempDir() / "t.txt", "0.5 1 2 3 0 0 0.6 0.8004\n");
  const auto traj = ReadTrajectory(path, F::kTum);
  ASSERT_EQ(traj.size(), 1u);
  EXPECT_NEAR(traj.poses[0].world_from_cam.rotation.norm(), 1.0, 1e-15);
  EXPECT_NEAR(traj.poses[0].world_from_cam.rotation.w(), 0.8004 / std::hypot(0.6, 0.8004), 1e-15);
  EXPECT_DOUBLE_EQ(traj.poses[0].timestamp, 0.5);
}

TEST(TrajectoryRead, NearlyOrthonormalKittiBlockIsReorthonormalised) {
  // A rotation about z by 0.3 rad with entries rounded to 4 decimals (|R^T R - I| ~ 1e-4).
  const auto path =
      test::WriteText(test::TempDir() / "k.txt", "0.9553 -0.2955 0 1 0.2955 0.9553 0 2 0 0 1 3\n");
  const auto traj = ReadTrajectory(path, F::kKitti);
  ASSERT_EQ(traj.size(), 1u);
  const Eigen::Matrix3d r = traj.poses[0].world_from_cam.RotationMatrix();
  EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(LogSO3(traj.poses[0].world_from_cam.rotation).z(), 0.3, 2e-4);
  EXPECT_EQ(traj.poses[0].world_from_cam.translation, Eigen::Vector3d(1, 2, 3));
}

TEST(TrajectoryRead, KnownAnswersPerFormat) {
  const auto dir = test::TempDir();
  {
    const auto t = ReadTrajectory(
        test::WriteText(dir / "a.txt", "# t x y z qx qy qz qw\r\n10.25 1 2 3 0 0 1 0\r\n"),
        F::kAuto);
    ASSERT_EQ(t.size(), 1u);
    EXPECT_TRUE(t.has_rotation && t.has_timestamps);
    EXPECT_DOUBLE_EQ(t.poses[0].timestamp, 10.25);
    EXPECT_EQ(t.poses[0].frame, 0);
    // qz = 1: rotation by pi about z maps x to -x.
    EXPECT_TRUE((t.poses[0].world_from_cam.rotation * Eigen::Vector3d::UnitX())
                    .isApprox(-Eigen::Vector3d::UnitX()));
  }
  {
    const auto t = ReadTrajectory(
        test::WriteText(dir / "b.csv",
                        "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x "
                        "[],q_RS_y [],q_RS_z [],v_x\n"
                        "1403636580838555648, 4.5, -1.5, 0.75, 0, 1, 0, 0, 0.1\n"),
        F::kAuto);
    ASSERT_EQ(t.size(), 1u);
    EXPECT_NEAR(t.poses[0].timestamp, 1403636580.838555648, 1e-6);
    EXPECT_EQ(t.poses[0].world_from_cam.translation, Eigen::Vector3d(4.5, -1.5, 0.75));
    // qw first: (0, 1, 0, 0) is pi about x, mapping y to -y.
    EXPECT_TRUE((t.poses[0].world_from_cam.rotation * Eigen::Vector3d::UnitY())
                    .isApprox(-Eigen::Vector3d::UnitY()));
  }
  {
    const auto t =
        ReadTrajectory(test::WriteText(dir / "c.txt", "7 1 2 3 9 9 9\n9 4 5 6 9 9 9\n"), F::kAuto);
    ASSERT_EQ(t.size(), 2u);
    EXPECT_FALSE(t.has_rotation);
    EXPECT_FALSE(t.has_timestamps);
    EXPECT_EQ(t.poses[1].frame, 9);
    EXPECT_DOUBLE_EQ(t.poses[1].timestamp, 9.0);
    EXPECT_EQ(t.poses[1].world_from_cam.translation, Eigen::Vector3d(4, 5, 6));
  }
  {
    const auto t =
        ReadTrajectory(test::WriteText(dir / "d.txt", "0 -1 0 5 1 0 0 6 0 0 1 7\n"), F::kAuto);
    ASSERT_EQ(t.size(), 1u);
    EXPECT_FALSE(t.has_timestamps);
    EXPECT_TRUE(t.poses[0].world_from_cam.RotationMatrix().isApprox(
        (Eigen::Matrix3d() << 0, -1, 0, 1, 0, 0, 0, 0, 1).finished()));
    EXPECT_EQ(t.poses[0].world_from_cam.translation, Eigen::Vector3d(5, 6, 7));
  }
}

// ------------------------------------------------------------------------------ auto-detection

TEST(TrajectoryDetect, RuleTable) {
  struct Case {
    const char* line;
    F expected;
  };
  const Case cases[] = {
      {"1.5 0 0 0 0 0 0 1", F::kTum},
      {"3 0 0 0 0 0 0 1", F::kTum},                   // integer time, unit quaternion -> TUM
      {"3 1 2 3 4 5 6 7", F::kPositions},             // integer first column, not a quaternion
      {"3.5 1 2 3 4 5 6 7", F::kTum},                 // fallback: TUM (the reader then fails)
      {"1 0 0 0 0 1 0 0 0 0 1 0", F::kKitti},         // integer-looking rotation -> KITTI
      {"1 2 3 4 5 6 7 8 9 10 11 12", F::kPositions},  // not a rotation, integer first column
      {"1.0 2 3 4 5 6 7 8 9 10 11 12", F::kKitti},    // fallback: KITTI (the reader then fails)
      {"2 1 0 0 0 0 1 0 0 0 0 1 0", F::kKitti},       // indexed KITTI
      {"0 1 2 3", F::kPositions},
      {"0 1 2 3 4 5 6", F::kPositions},
      {"100,1,2,3,1,0,0,0", F::kEuroc},
      {"100, 1, 2, 3", F::kEuroc},  // commas decide; the EuRoC reader rejects the column count
  };
  const auto dir = test::TempDir();
  for (const auto& c : cases) {
    SCOPED_TRACE(c.line);
    const auto path = test::WriteText(dir / "d.txt", std::string("# header\n\n") + c.line + "\n");
    EXPECT_EQ(DetectTrajectoryFormat(path), c.expected);
  }
}

TEST(TrajectoryDetect, OverrideAlwaysWins) {
  const auto dir = test::TempDir();
  // Auto-detects as TUM (unit quaternion) but is read as positions when asked.
  const auto path = test::WriteText(dir / "x.txt", "3 1 2 3 0 0 0 1\n4 1 2 3 0 0 0 1\n");
  EXPECT_EQ(DetectTrajectoryFormat(path), F::kTum);
  const auto as_positions = ReadTrajectory(path, F::kPositions);
  EXPECT_FALSE(as_positions.has_rotation);
  EXPECT_EQ(as_positions.poses[1].frame, 4);
  // A positions file forced to TUM fails with the TUM expectation.
  const auto pos = test::WriteText(dir / "p.txt", "0 1 2 3 4 5 6\n");
  try {
    ReadTrajectory(pos, F::kTum);
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(e.expected().find("TUM"), std::string::npos);
  }
}

// ------------------------------------------------------------------------------------ writing

Trajectory RandomTrajectory(size_t n, uint64_t salt, double t0) {
  auto rng = test::SeededRng(salt);
  std::normal_distribution<double> normal(0.0, 3.0);
  std::uniform_real_distribution<double> dt(0.01, 0.2);
  Trajectory traj;
  double t = t0;
  for (size_t i = 0; i < n; ++i) {
    StampedPose p;
    p.frame = static_cast<int64_t>(i);
    p.timestamp = t;
    t += dt(rng);
    p.world_from_cam = Rigid3d(ExpSO3(Eigen::Vector3d(normal(rng), normal(rng), normal(rng))),
                               Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 10.0);
    traj.poses.push_back(p);
  }
  return traj;
}

void ExpectSamePoses(const Trajectory& a, const Trajectory& b, double time_tol, double pos_tol,
                     double rot_tol) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_NEAR(a.poses[i].timestamp, b.poses[i].timestamp, time_tol) << i;
    EXPECT_EQ(a.poses[i].frame, b.poses[i].frame) << i;
    EXPECT_LE((a.poses[i].world_from_cam.translation - b.poses[i].world_from_cam.translation)
                  .cwiseAbs()
                  .maxCoeff(),
              pos_tol)
        << i;
    EXPECT_LE(RotationAngle(a.poses[i].world_from_cam.rotation, b.poses[i].world_from_cam.rotation),
              rot_tol)
        << i;
  }
}

TEST(TrajectoryWrite, TumRoundTripIsExactUpToTimePrecision) {
  const auto traj = RandomTrajectory(200, 1, 1311868164.363181);
  const auto path = test::TempDir() / "t.txt";
  WriteTrajectory(path, traj, F::kTum);
  EXPECT_EQ(DetectTrajectoryFormat(path), F::kTum);
  const auto back = ReadTrajectory(path);
  EXPECT_TRUE(back.has_rotation && back.has_timestamps);
  ExpectSamePoses(traj, back, 1e-6, 0.0, 1e-12);  // %.9f of ~1e9 s: limited by double
  // Positions are written with shortest round-trip precision: bit-exact (checked above with 0).
  EXPECT_EQ(back.poses[7].world_from_cam.translation, traj.poses[7].world_from_cam.translation);
}

TEST(TrajectoryWrite, TumTimeHasNineDecimals) {
  Trajectory traj;
  traj.poses.push_back(StampedPose{0.5, 0, Rigid3d()});
  const auto path = test::TempDir() / "t.txt";
  WriteTrajectory(path, traj, F::kTum);
  EXPECT_NE(test::ReadText(path).find("\n0.500000000 0 0 0 0 0 0 1\n"), std::string::npos)
      << test::ReadText(path);
}

// Times closer than a writer's resolution. TUM writes each time with the digits that read back as
// the same double (9 decimals when they do), so distinct times stay distinct through a file. EuRoC
// CSV holds integer nanoseconds: times less than 1 ns apart, or beyond the int64 range, are refused
// naming the frame before the file is touched. (Both were written equal, or as
// -9223372036854775808, and then refused by our own reader.)
TEST(TrajectoryWrite, CloseTimestampsRoundTripOrAreRefusedUpFront) {
  const auto dir = test::TempDir();
  auto traj = RandomTrajectory(6, 6, 0.0);
  const double times[] = {1e-12,       2e-12,          0.5,
                          0.5 + 1e-10, 1311868229.576, std::nextafter(1311868229.576, 2e9)};
  for (size_t i = 0; i < traj.size(); ++i) traj.poses[i].timestamp = times[i];
  WriteTrajectory(dir / "t.txt", traj, F::kTum);
  const Trajectory back = ReadTrajectory(dir / "t.txt");
  ASSERT_EQ(back.size(), traj.size());
  for (size_t i = 0; i < traj.size(); ++i) EXPECT_EQ(back.poses[i].timestamp, times[i]) << i;
  EXPECT_NE(test::ReadText(dir / "t.txt").find("\n0.500000000 "), std::string::npos)
      << "times that 9 decimals hold keep them";

  // EuRoC: whole nanoseconds round-trip exactly; closer times and huge ones are refused.
  for (size_t i = 0; i < traj.size(); ++i) traj.poses[i].timestamp = 7.0 + 1e-9 * i;
  WriteTrajectory(dir / "e.csv", traj, F::kEuroc);
  const Trajectory e = ReadTrajectory(dir / "e.csv");
  for (size_t i = 0; i < traj.size(); ++i)
    EXPECT_EQ(e.poses[i].timestamp, 7.0 + 1e-9 * static_cast<double>(i)) << i;
  const auto refused = [&](double t3, const std::string& message) {
    SCOPED_TRACE(message);
    traj.poses[3].timestamp = t3;
    for (size_t i = 4; i < traj.size(); ++i) traj.poses[i].timestamp = t3 + i;
    try {
      WriteTrajectory(dir / "refused.csv", traj, F::kEuroc);
      ADD_FAILURE() << "no throw";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("refused.csv"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir / "refused.csv"));
  };
  refused(traj.poses[2].timestamp + 1e-10, "frame 3");
  refused(1e10, "frame 3");
}

// A '#' that starts a token ends the data of a line ("1 0 0 ... 1  # start"), as on a line of its
// own; one inside a token is still an error.
TEST(TrajectoryRead, ATrailingCommentEndsTheLine) {
  const auto dir = test::TempDir();
  const auto tum = test::WriteText(
      dir / "t.txt", "0 0 0 0 0 0 0 1 # start\n1 1 0 0 0 0 0 1\t#\n2 2 0 0 0 0 0 1 #x #y\n");
  EXPECT_EQ(DetectTrajectoryFormat(tum), F::kTum);
  EXPECT_EQ(ReadTrajectory(tum).size(), 3u);
  const auto kitti = test::WriteText(dir / "k.txt", "1 0 0 0 0 1 0 0 0 0 1 0 # frame 0\n");
  EXPECT_EQ(ReadTrajectory(kitti).size(), 1u);
  const auto glued = test::WriteText(dir / "g.txt", "0 0 0 0 0 0 0 1#start\n");
  EXPECT_THROW(ReadTrajectory(glued, F::kTum), FileError);
}

TEST(TrajectoryWrite, KittiRoundTrip) {
  auto traj = RandomTrajectory(150, 2, 0.0);
  traj.has_timestamps = false;
  for (auto& p : traj.poses) p.timestamp = static_cast<double>(p.frame);
  const auto path = test::TempDir() / "k.txt";
  WriteTrajectory(path, traj, F::kKitti);
  EXPECT_EQ(DetectTrajectoryFormat(path), F::kKitti);
  const auto back = ReadTrajectory(path);
  EXPECT_FALSE(back.has_timestamps);
  ExpectSamePoses(traj, back, 0.0, 0.0, 1e-12);
  // 12 numbers per line, as the devkit reads.
  const auto first_line = test::ReadText(path).substr(0, test::ReadText(path).find('\n'));
  EXPECT_EQ(std::count(first_line.begin(), first_line.end(), ' '), 11);
}

TEST(TrajectoryWrite, EurocRoundTrip) {
  const auto traj = RandomTrajectory(120, 3, 1403636580.83856);
  const auto path = test::TempDir() / "e.csv";
  WriteTrajectory(path, traj, F::kEuroc);
  EXPECT_EQ(DetectTrajectoryFormat(path), F::kEuroc);
  const auto back = ReadTrajectory(path);
  ExpectSamePoses(traj, back, 1e-6, 0.0, 1e-12);
}

TEST(TrajectoryWrite, PositionsRoundTrip) {
  auto traj = RandomTrajectory(50, 4, 0.0);
  traj.has_rotation = false;
  traj.has_timestamps = false;
  for (auto& p : traj.poses) {
    p.frame = 3 * p.frame + 5;
    p.timestamp = static_cast<double>(p.frame);
    p.world_from_cam.rotation = Eigen::Quaterniond::Identity();
  }
  const auto path = test::TempDir() / "p.txt";
  WriteTrajectory(path, traj, F::kPositions);
  const auto back = ReadTrajectory(path, F::kPositions);
  EXPECT_FALSE(back.has_rotation);
  ExpectSamePoses(traj, back, 0.0, 0.0, 0.0);
}

TEST(TrajectoryWrite, RejectsAutoAndPositionsOnlyAsPoseFormats) {
  const auto dir = test::TempDir();
  auto traj = RandomTrajectory(3, 5, 0.0);
  EXPECT_THROW(WriteTrajectory(dir / "a.txt", traj, F::kAuto), std::invalid_argument);
  traj.has_rotation = false;
  EXPECT_THROW(WriteTrajectory(dir / "b.txt", traj, F::kTum), std::invalid_argument);
  EXPECT_THROW(WriteTrajectory(dir / "c.txt", traj, F::kKitti), std::invalid_argument);
  EXPECT_FALSE(std::filesystem::exists(dir / "b.txt"));
}

// ---------------------------------------------------------------------------------- real data

TEST(TrajectoryRealData, KittiGroundTruth00) {
  SL_REQUIRE_DATA("kitti_gt_poses");
  const auto path = test::DataDir() / "kitti_gt_poses/00.txt";
  EXPECT_EQ(DetectTrajectoryFormat(path), F::kKitti);
  const auto traj = ReadTrajectory(path);
  EXPECT_EQ(traj.size(), 4541u);
  EXPECT_FALSE(traj.has_timestamps);
  EXPECT_EQ(traj.poses.back().frame, 4540);
  // Line 2 of the file: "... -4.690294e-02 ... -2.839928e-02 ... 8.586941e-01".
  EXPECT_TRUE(traj.poses[1].world_from_cam.translation.isApprox(
      Eigen::Vector3d(-4.690294e-02, -2.839928e-02, 8.586941e-01), 1e-12));
}

TEST(TrajectoryRealData, IndexedKitti09StartsAtFrameTwo) {
  SL_REQUIRE_DATA("vslam_trajectories/kitti09_10");
  const auto path = test::DataDir() / "vslam_trajectories/kitti09_10/example_0/09.txt";
  EXPECT_EQ(DetectTrajectoryFormat(path), F::kKitti);
  const auto traj = ReadTrajectory(path);
  ASSERT_GT(traj.size(), 2u);
  EXPECT_EQ(traj.poses[0].frame, 2);
  EXPECT_EQ(traj.poses[1].frame, 3);
  EXPECT_TRUE(traj.poses[1].world_from_cam.translation.isApprox(
      Eigen::Vector3d(0.0004207776345156093, -3.191738823975447e-05, 0.015278999087073218), 1e-12));
}

TEST(TrajectoryRealData, EurocTumFilesAndPositionsFile) {
  SL_REQUIRE_DATA("vslam_trajectories/euroc");
  const auto root = test::DataDir() / "vslam_trajectories";
  for (const char* rel : {"euroc/MH_01/vio_mono_estimate.txt", "euroc/MH_01_easy.txt",
                          "tum/freiburg1_xyz-groundtruth.txt", "tum/freiburg1_xyz-rgbdslam.txt"}) {
    SCOPED_TRACE(rel);
    EXPECT_EQ(DetectTrajectoryFormat(root / rel), F::kTum);
    const auto traj = ReadTrajectory(root / rel);
    EXPECT_GT(traj.size(), 100u);
    EXPECT_TRUE(traj.has_rotation && traj.has_timestamps);
  }
  const auto gt = ReadTrajectory(root / "euroc/MH_01_easy.txt");
  EXPECT_NEAR(gt.poses[0].timestamp, 1403636580.83856, 1e-6);
  EXPECT_TRUE(gt.poses[0].world_from_cam.translation.isApprox(
      Eigen::Vector3d(4.688319, -1.786938, 0.783338), 1e-12));
  EXPECT_NEAR(gt.poses[0].world_from_cam.rotation.w(), 0.534108, 1e-5);

  const auto pos_path = root / "kitti00/kitti_sift_flannmatch.txt";
  EXPECT_EQ(DetectTrajectoryFormat(pos_path), F::kPositions);
  const auto pos = ReadTrajectory(pos_path);
  EXPECT_FALSE(pos.has_rotation);
  EXPECT_EQ(pos.poses[1].frame, 1);
  EXPECT_TRUE(pos.poses[1].world_from_cam.translation.isApprox(
      Eigen::Vector3d(0.0002957844738799962, 0.0034938993082787233, 0.8604357427717315), 1e-12));
}

TEST(TrajectoryRealData, TumFr2DeskGroundTruthRepeatsATimestamp) {
  SL_REQUIRE_DATA("vslam_trajectories/tum");
  const auto path = test::DataDir() / "vslam_trajectories/tum/fr2_desk_groundtruth.txt";
  // Lines 10862 and 10863 of the official file both start with 1311868229.5760.
  try {
    ReadTrajectory(path);
    FAIL() << "expected FileError";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 10863) << e.what();
  }
  TrajectoryReadOptions lenient;
  lenient.drop_duplicate_timestamps = true;
  const auto traj = ReadTrajectory(path, F::kAuto, lenient);
  EXPECT_EQ(traj.size(), 20957u - 1u);  // 20957 data lines (20960 - 3 comments) - the repeat
  for (size_t i = 1; i < traj.size(); ++i) {
    ASSERT_GT(traj.poses[i].timestamp, traj.poses[i - 1].timestamp);
  }
  // The first of the two equal stamps is kept: (1.4054, 0.9615, 1.3677).
  const auto it = std::find_if(traj.poses.begin(), traj.poses.end(), [](const StampedPose& p) {
    return std::abs(p.timestamp - 1311868229.5760) < 1e-6;
  });
  ASSERT_NE(it, traj.poses.end());
  EXPECT_TRUE(it->world_from_cam.translation.isApprox(Eigen::Vector3d(1.4054, 0.9615, 1.3677)));
}

// The strict reader's error on a repeated timestamp / frame index names the option that reads
// such files; a decreasing one does not (dropping repeats would not help).
TEST(TrajectoryRead, RepeatedTimestampErrorNamesDropDuplicates) {
  const auto dir = test::TempDir();
  const std::pair<std::string, F> repeats[] = {
      {"1 0 0 0 0 0 0 1\n1 5 0 0 0 0 0 1\n", F::kTum},
      {"5,0,0,0,1,0,0,0\n5,1,0,0,1,0,0,0\n", F::kEuroc},
      {"4 1 0 0 0 0 1 0 0 0 0 1 0\n4 1 0 0 1 0 1 0 0 0 0 1 0\n", F::kKitti},
  };
  int k = 0;
  for (const auto& [text, format] : repeats) {
    const auto path = test::WriteText(dir / fmt::format("r{}.txt", k++), text);
    try {
      ReadTrajectory(path, format);
      ADD_FAILURE() << "accepted a repeat: " << text;
    } catch (const FileError& e) {
      EXPECT_EQ(e.line(), 2);
      EXPECT_NE(std::string(e.what()).find("sparseloop convert --drop-duplicates"),
                std::string::npos)
          << e.what();
    }
  }
  const auto decreasing = test::WriteText(dir / "d.txt", "2 0 0 0 0 0 0 1\n1 5 0 0 0 0 0 1\n");
  try {
    ReadTrajectory(decreasing, F::kTum);
    ADD_FAILURE() << "accepted a decreasing timestamp";
  } catch (const FileError& e) {
    EXPECT_EQ(std::string(e.what()).find("--drop-duplicates"), std::string::npos) << e.what();
  }
}

TEST(TrajectoryRead, DropDuplicatesOptionKeepsFirstAndStillRejectsDecreasing) {
  const auto dir = test::TempDir();
  TrajectoryReadOptions lenient;
  lenient.drop_duplicate_timestamps = true;
  const auto tum =
      test::WriteText(dir / "t.txt", "1 0 0 0 0 0 0 1\n1 5 0 0 0 0 0 1\n2 6 0 0 0 0 0 1\n");
  const auto t = ReadTrajectory(tum, F::kTum, lenient);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t.poses[0].world_from_cam.translation.x(), 0.0);
  EXPECT_EQ(t.poses[1].frame, 1);
  const auto bad = test::WriteText(dir / "b.txt", "2 0 0 0 0 0 0 1\n1 5 0 0 0 0 0 1\n");
  EXPECT_THROW(ReadTrajectory(bad, F::kTum, lenient), FileError);
  const auto kitti =
      test::WriteText(dir / "k.txt", "4 1 0 0 0 0 1 0 0 0 0 1 0\n4 1 0 0 1 0 1 0 0 0 0 1 0\n");
  EXPECT_EQ(ReadTrajectory(kitti, F::kKitti, lenient).size(), 1u);
  const auto euroc =
      test::WriteText(dir / "e.csv", "5,0,0,0,1,0,0,0\n5,1,0,0,1,0,0,0\n6,1,0,0,1,0,0,0\n");
  EXPECT_EQ(ReadTrajectory(euroc, F::kEuroc, lenient).size(), 2u);
}

}  // namespace
}  // namespace sparseloop
