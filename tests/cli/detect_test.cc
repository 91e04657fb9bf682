// End-to-end tests of `sparseloop detect`.
#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

std::string ReadAll(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(CliDetect, CastleWithoutPosesFindsTheRingClosure) {
  SL_REQUIRE_DATA("castle_p30_768");
  const auto out = TempDir();
  const CliResult r =
      RunCli({"detect", "--dataset", "images:" + (DataDir() / "castle_p30_768" / "images").string(),
              "--intrinsics", kCastleIntrinsics, "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string csv = ReadAll(out / "loops.csv");
  std::istringstream lines(csv);
  std::string header;
  std::getline(lines, header);
  EXPECT_EQ(header,
            "query,match,score,inliers,status,pose_kind,planar_alternative,qx,qy,qz,qw,tx,ty,tz,"
            "scale,match_session,query_image,match_image,method,"
            "local_poses_from_images,local_poses_raw");
  int loops = 0, planar = 0;
  bool ring = false;
  for (std::string line; std::getline(lines, line);) {
    int q = -1, m = -1;
    ASSERT_EQ(std::sscanf(line.c_str(), "%d,%d", &q, &m), 2) << line;
    EXPECT_GT(q, m);
    std::vector<std::string> fields;
    std::istringstream row(line);
    for (std::string f; std::getline(row, f, ',');) fields.push_back(f);
    ASSERT_EQ(fields.size(), 21u) << line;
    EXPECT_EQ(fields[16], fmt::format("{:04d}.jpg", q));  // the images' file names
    EXPECT_EQ(fields[17], fmt::format("{:04d}.jpg", m));
    EXPECT_EQ(fields[4], "detected");
    // No depths: the essential matrix's unit direction, or the local map's PnP / Sim(3).
    EXPECT_TRUE(fields[5] == "se3_unit_translation" || fields[5] == "se3_metric" ||
                fields[5] == "sim3")
        << line;
    // No poses, so no pose prior to pick a planar alternative with.
    EXPECT_EQ(fields[6], "0") << line;
    planar += fields[6] == "1";
    // Frame indices of images:DIR are 0-based: view 0029 is index 29, views 0000-0002 are 0-2.
    ring = ring || (q >= 28 && m <= 2);
    ++loops;
  }
  EXPECT_TRUE(ring) << csv;
  const auto summary = nlohmann::json::parse(ReadAll(out / "summary.json"));
  EXPECT_EQ(summary["keyframes"].get<int>(), 30);
  EXPECT_EQ(summary["loops"].get<int>(), loops);
  EXPECT_EQ(summary["planar_alternatives"].get<int>(), planar);
  EXPECT_EQ(summary["search"].get<std::string>(), "global");
  EXPECT_GT(summary["bytes_per_keyframe"].get<double>(), 0.0);
  for (const char* stage : {"extract", "search", "match", "verify", "total"}) {
    ASSERT_TRUE(summary["timing_ms"].contains(stage)) << stage;
    EXPECT_LE(summary["timing_ms"][stage]["median"].get<double>(),
              summary["timing_ms"][stage]["max"].get<double>());
  }
  EXPECT_GT(summary["total_ms"].get<double>(), 0.0);
  // frames.csv: every detected frame lists its match among the keyframes it verified.
  std::istringstream frames(ReadAll(out / "frames.csv"));
  std::getline(frames, header);
  EXPECT_EQ(header,
            "frame,status,candidates,matches,inliers,match,source,verified_area,"
            "verified_appearance,appearance_candidates,pose_segment,pose_reset,area");
  int detected = 0;
  for (std::string line; std::getline(frames, line);) {
    std::vector<std::string> fields;
    std::istringstream row(line);
    for (std::string f; std::getline(row, f, ',');) fields.push_back(f);
    if (fields.size() < 8 || fields[1] != "detected") continue;
    ++detected;
    std::vector<std::string> ids;
    std::istringstream verified(fields[7]);
    for (std::string id; std::getline(verified, id, ';');) ids.push_back(id);
    EXPECT_FALSE(ids.empty()) << line;
    EXPECT_LE(ids.size(), 3u) << line;
    // Without poses every candidate to verify is verified and the most inliers kept
    // (detector.best_of_verified): the match is one of them, not necessarily the last.
    EXPECT_NE(std::find(ids.begin(), ids.end(), fields[5]), ids.end()) << line;
  }
  EXPECT_EQ(detected, loops);
}

// `detect` runs `run`'s driver: an unreadable image is skipped (logged, counted), not fatal, and
// the stage times go to timings.csv as `run` writes them.
TEST(CliDetect, SkipsAnUnreadableImageAndWritesTimingsAsRunDoes) {
  SL_REQUIRE_DATA("castle_p30_768");
  const auto dir = TempDir();
  const auto images = dir / "images";
  std::filesystem::copy(DataDir() / "castle_p30_768" / "images", images);
  std::ofstream(images / "0010.jpg", std::ios::trunc) << "not an image";
  const auto out = dir / "out";
  const CliResult r = RunCli({"detect", "--dataset", "images:" + images.string(), "--intrinsics",
                              kCastleIntrinsics, "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("skipping frame 10"), std::string::npos) << r.err;
  const auto summary = nlohmann::json::parse(ReadAll(out / "summary.json"));
  EXPECT_EQ(summary["skipped_frames"].get<int>(), 1);
  EXPECT_EQ(summary["keyframes"].get<int>(), 29);
  std::istringstream timings(ReadAll(out / "timings.csv"));
  std::string line;
  ASSERT_TRUE(std::getline(timings, line));
  EXPECT_EQ(line, "keyframe,status,extract_ms,search_ms,match_ms,verify_ms,total_ms");
  int rows = 0;
  bool has_frame_10 = false;
  while (std::getline(timings, line)) {
    ++rows;
    has_frame_10 |= line.rfind("10,", 0) == 0;
  }
  EXPECT_EQ(rows, 29);
  EXPECT_FALSE(has_frame_10);
  const std::string loops = ReadAll(out / "loops.csv");  // the ring still closes
  EXPECT_TRUE(loops.find("\n29,") != std::string::npos || loops.find("\n28,") != std::string::npos)
      << loops;
}

TEST(CliDetect, SmallKChangesBytesPerKeyframe) {
  SL_REQUIRE_DATA("castle_p30_768");
  const auto out = TempDir();
  const CliResult r =
      RunCli({"detect", "--dataset", "images:" + (DataDir() / "castle_p30_768" / "images").string(),
              "--intrinsics", kCastleIntrinsics, "-K", "15", "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = nlohmann::json::parse(ReadAll(out / "summary.json"));
  EXPECT_LE(summary["bytes_per_keyframe"].get<double>(), 1024.0);
  EXPECT_EQ(summary["config"]["features"]["max_features"].get<int>(), 15);
}

// A rendered folder holds poses.txt (its ground truth). Without --poses, `detect` must not search
// with it as if a vSLAM had estimated it: no raw poses, the global search, said on stderr.
TEST(CliDetect, FolderGroundTruthIsNeverUsedAsRawPoses) {
  const std::filesystem::path& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty());
  ASSERT_TRUE(std::filesystem::exists(seq / "poses.txt"));
  const auto out = TempDir();
  const CliResult r =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "-K", "50", "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("no --poses"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ground truth is not used as raw poses"), std::string::npos) << r.err;
  const auto summary = nlohmann::json::parse(ReadAll(out / "summary.json"));
  EXPECT_EQ(summary["search"].get<std::string>(), "global");
  EXPECT_FALSE(summary.contains("poses_file")) << summary.dump();
  // With --poses the same folder is searched with the raw poses.
  const auto out2 = TempDir() / "with_poses";
  const CliResult r2 =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "-K", "50", "--poses",
              (seq / "poses_raw.txt").string(), "--out", out2.string()});
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  const auto summary2 = nlohmann::json::parse(ReadAll(out2 / "summary.json"));
  EXPECT_EQ(summary2["poses_file"].get<std::string>(), (seq / "poses_raw.txt").string());
  EXPECT_NE(summary2["search"].get<std::string>(), "global");
}

TEST(CliDetect, PaperSearchWithoutPosesExits2) {
  SL_REQUIRE_DATA("castle_p30_768");
  const auto out = TempDir();
  const CliResult r =
      RunCli({"detect", "--dataset", "images:" + (DataDir() / "castle_p30_768" / "images").string(),
              "--intrinsics", kCastleIntrinsics, "--search", "paper", "--out", out.string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("needs poses"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out / "loops.csv"));
}

TEST(CliDetect, BadArgumentsExit2) {
  const auto out = TempDir();
  EXPECT_EQ(RunCli({"detect", "--out", out.string()}).exit_code, 2);  // --dataset missing
  EXPECT_EQ(RunCli({"detect", "--dataset", "images:/nonexistent/dir", "--intrinsics",
                    "500,500,320,240", "--out", out.string()})
                .exit_code,
            2);
  const CliResult bad_k = RunCli({"detect", "--dataset", "images:" + out.string(), "--intrinsics",
                                  "1,2,3", "--out", out.string()});
  EXPECT_EQ(bad_k.exit_code, 2);
  EXPECT_NE(bad_k.err.find("fx,fy,cx,cy"), std::string::npos) << bad_k.err;
  const CliResult bad_search = RunCli({"detect", "--dataset", "images:" + out.string(), "--search",
                                       "sideways", "--out", out.string()});
  EXPECT_EQ(bad_search.exit_code, 2);
}

}  // namespace
}  // namespace sparseloop::test
