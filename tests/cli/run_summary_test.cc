// What `run` / `detect` write about a run (docs/FORMATS.md): summary.json's loop checks, and
// the per-frame status.
#include <fstream>
#include <sstream>
#include <set>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

nlohmann::json ReadJson(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

// Rows of a CSV as header-name -> value maps.
std::vector<std::map<std::string, std::string>> ReadCsv(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::istringstream hs(line);
  for (std::string f; std::getline(hs, f, ',');) header.push_back(f);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::map<std::string, std::string> row;
    std::istringstream ls(line);
    size_t i = 0;
    for (std::string f; std::getline(ls, f, ','); ++i) row[i < header.size() ? header[i] : ""] = f;
    rows.push_back(row);
  }
  return rows;
}

// Ran once: the rendered loop sequence through `run` with its GT.
const fs::path& RunOnRenderedSequence() {
  static const fs::path out = [] {
    const fs::path& seq = RenderedLoopSequence();
    const fs::path dir = TempDir("_shared_run") / "out";
    const CliResult r = RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                                (seq / "poses_raw.txt").string(), "--out", dir.string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return dir;
  }();
  return out;
}

TEST(CliRunSummary, LoopChecksListEveryAcceptedLoop) {
  const fs::path& out = RunOnRenderedSequence();
  const auto summary = ReadJson(out / "summary.json");
  ASSERT_TRUE(summary.contains("loop_checks")) << summary.dump(1);
  const auto& checks = summary["loop_checks"];
  ASSERT_TRUE(checks.is_array());
  std::set<std::pair<int, int>> accepted;
  for (const auto& row : ReadCsv(out / "loops.csv"))
    if (row.at("accepted") == "1") accepted.insert({std::stoi(row.at("query")), std::stoi(row.at("match"))});
  ASSERT_FALSE(accepted.empty());
  EXPECT_EQ(checks.size(), accepted.size());
  EXPECT_EQ(summary["accepted_loops"].get<size_t>(), accepted.size());
  size_t inconsistent = 0;
  for (const auto& c : checks) {
    EXPECT_TRUE(accepted.count({c["query"].get<int>(), c["match"].get<int>()})) << c.dump();
    EXPECT_GE(c["chi2"].get<double>(), 0.0);
    EXPECT_GT(c["dof"].get<int>(), 0);
    EXPECT_GT(c["threshold"].get<double>(), 0.0);
    EXPECT_EQ(c["consistent"].get<bool>(), c["chi2"].get<double>() <= c["threshold"].get<double>());
    for (const char* key : {"loop", "translation_error", "rotation_error_rad", "log_scale_error"})
      EXPECT_TRUE(c.contains(key)) << key;
    inconsistent += !c["consistent"].get<bool>();
  }
  EXPECT_EQ(summary["inconsistent_loops"].get<size_t>(), inconsistent);
}

}  // namespace
}  // namespace sparseloop::test
