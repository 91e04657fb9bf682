// End-to-end tests of `sparseloop detect --map FILE` (multi-session loop closure through the CLI).
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Camera centre of castle view i (Strecha format: K 3x3, 3 zeros, R 3x3, centre, w h).
Eigen::Vector3d CastleCentre(int i) {
  char name[64];
  std::snprintf(name, sizeof(name), "%04d.jpg.camera", i);
  std::ifstream in(DataDir() / "castle_p30_768" / "gt_dense_cameras" / name);
  std::vector<double> v;
  for (double x; in >> x;) v.push_back(x);
  EXPECT_GE(v.size(), 24u) << name;
  return v.size() >= 24 ? Eigen::Vector3d(v[21], v[22], v[23]) : Eigen::Vector3d::Zero();
}

struct CsvLoop {
  int query = -1, match = -1, match_session = -1;
};

std::vector<CsvLoop> ReadLoops(const std::filesystem::path& path) {
  std::istringstream lines(Slurp(path));
  std::string header;
  std::getline(lines, header);
  EXPECT_EQ(header,
            "query,match,score,inliers,status,pose_kind,planar_alternative,qx,qy,qz,qw,tx,ty,tz,"
            "scale,match_session,query_image,match_image,method,"
            "local_poses_from_images,local_poses_raw");
  std::vector<CsvLoop> out;
  for (std::string line; std::getline(lines, line);) {
    CsvLoop l;
    l.query = std::stoi(line.substr(0, line.find(',')));
    l.match = std::stoi(line.substr(line.find(',') + 1));
    std::vector<std::string> fields;
    std::istringstream row(line);
    for (std::string f; std::getline(row, f, ',');) fields.push_back(f);
    l.match_session = std::stoi(fields.at(15));
    out.push_back(l);
  }
  return out;
}

TEST(CliDetectMap, SecondRunOnTheSameDataFindsLoopsIntoSessionOne) {
  SL_REQUIRE_DATA("castle_p30_768");
  const auto dir = TempDir("detect_map");
  const auto map = dir / "map.db";
  const std::string images = "images:" + (DataDir() / "castle_p30_768" / "images").string();
  auto run = [&](const std::string& out) {
    return RunCli({"detect", "--dataset", images, "--intrinsics", kCastleIntrinsics, "--map",
                   map.string(), "--out", (dir / out).string()});
  };
  const CliResult first = run("one");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  for (const CsvLoop& l : ReadLoops(dir / "one" / "loops.csv")) EXPECT_EQ(l.match_session, 0);
  const auto s1 = nlohmann::json::parse(Slurp(dir / "one" / "summary.json"));
  EXPECT_EQ(s1["map"]["session"].get<int>(), 1);
  EXPECT_EQ(s1["map"]["prior_keyframes"].get<int>(), 0);

  const CliResult second = run("two");
  ASSERT_EQ(second.exit_code, 0) << second.err;
  const auto s2 = nlohmann::json::parse(Slurp(dir / "two" / "summary.json"));
  EXPECT_EQ(s2["map"]["session"].get<int>(), 2);
  EXPECT_EQ(s2["map"]["prior_keyframes"].get<int>(), 30);
  int cross = 0;
  for (const CsvLoop& l : ReadLoops(dir / "two" / "loops.csv")) {
    if (l.match_session == 0) continue;
    EXPECT_EQ(l.match_session, 1);
    ++cross;
    // Correct by GT: the two views are neighbours on the ring (steps are 3-10 m; 0029-0001 and
    // 0000-0009 are the closest pairs across the ring, 3.4 and 5.9 m).
    EXPECT_LT((CastleCentre(l.query) - CastleCentre(l.match)).norm(), 8.0)
        << l.query << " -> session 1 view " << l.match;
  }
  EXPECT_GE(cross, 20) << second.out;
  EXPECT_EQ(s2["cross_session_loops"].get<int>(), cross);
  EXPECT_NE(second.out.find("(session 1)"), std::string::npos) << second.out;
}

TEST(CliDetectMap, CorruptMapFileExits2WithItsName) {
  SL_REQUIRE_DATA("castle_p30_768");
  const auto dir = TempDir("detect_map_bad");
  const auto map = dir / "garbage.db";
  {
    std::ofstream out(map, std::ios::binary);
    for (int i = 0; i < 512; ++i) out << "this is not a sparseloop map ";
  }
  const CliResult r = RunCli(
      {"detect", "--dataset", "images:" + (DataDir() / "castle_p30_768" / "images").string(),
       "--intrinsics", kCastleIntrinsics, "--map", map.string(), "--out", (dir / "out").string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(map.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not a database"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out" / "loops.csv"));
}

}  // namespace
}  // namespace sparseloop::test
