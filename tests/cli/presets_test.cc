// The shipped presets (presets/*.json; docs/FORMATS.md, "Presets") as a user meets them: `run
// --preset NAME`, `config --dump --preset NAME`, and an unknown name.
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "sparseloop/pipeline/config.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

// What each preset's doc promises, on the rendered aerial circuit (two laps, 120 keyframes,
// raw ATE 5.8 m): its record size, and loops that bring the corrected ATE under 15 % of the raw
// one with at most one loop beyond the GT distance. Measured: sparse 816 B, 26 loops (1 beyond
// 10 m), 5.79 -> 0.46 m; dense 11,456 B, 32 loops (1), 5.79 -> 0.33 m.
TEST(CliPresets, EachPresetClosesTheCircuitAtItsRecordSize) {
  const auto& seq = RenderedLoopSequence();
  ASSERT_FALSE(seq.empty());
  struct Expected {
    std::string name;
    int k;
    double min_bytes, max_bytes;
  };
  for (const Expected& e :
       {Expected{"sparse", 20, 500, 1024}, Expected{"dense", 300, 8000, 16000}}) {
    SCOPED_TRACE(e.name);
    const auto out = TempDir() / e.name;
    const CliResult r =
        RunCli({"run", "--dataset", "kitti:" + seq.string(), "--poses",
                (seq / "poses_raw.txt").string(), "--gt", (seq / "poses_gt.txt").string(),
                "--preset", e.name, "--out", out.string(), "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json s = ReadJson(out / "summary.json");
    EXPECT_EQ(s["config"]["detector"]["features"]["max_features"], e.k);
    const double bytes = s["bytes_per_keyframe"].get<double>();
    EXPECT_GE(bytes, e.min_bytes);
    EXPECT_LE(bytes, e.max_bytes);
    EXPECT_GE(s["accepted_loops"].get<int>(), 20);
    EXPECT_LE(s["accepted_loops_false"].get<int>(), 1);
    const double raw = s["eval"]["raw"]["ate_rmse_m"].get<double>();
    const double corrected = s["eval"]["corrected"]["ate_rmse_m"].get<double>();
    EXPECT_LT(corrected, 0.15 * raw) << corrected << " of " << raw;
  }
}

// `config --dump --preset NAME` is the defaults with the preset's keys on top: every key the
// preset file sets has its value, every other key its default.
TEST(CliPresets, DumpShowsThePresetOverTheDefaults) {
  const nlohmann::json defaults = nlohmann::json::parse(RunCli({"config", "--dump"}).out);
  for (const std::string& name : PresetNames()) {
    SCOPED_TRACE(name);
    const CliResult r = RunCli({"config", "--dump", "--preset", name});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    nlohmann::json expected = defaults;
    nlohmann::json preset = PresetConfig(name);
    preset.erase("doc");
    expected.merge_patch(preset);
    EXPECT_EQ(nlohmann::json::parse(r.out), expected);
  }
}

// An unknown name is refused before any work, naming the flag and the shipped names.
TEST(CliPresets, AnUnknownPresetNamesTheFlagAndThePresets) {
  const auto dir = TempDir();
  const CliResult r =
      RunCli({"run", "--dataset", "images:" + (dir / "none").string(), "--poses",
              (dir / "none.txt").string(), "--preset", "tiny", "--out", (dir / "out").string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--preset tiny"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("dense | sparse"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
  // An empty value (`--preset "$UNSET"`) is an error too, not the defaults.
  const CliResult empty =
      RunCli({"run", "--dataset", "images:" + (dir / "none").string(), "--poses",
              (dir / "none.txt").string(), "--preset", "", "--out", (dir / "out").string()});
  EXPECT_EQ(empty.exit_code, 2) << empty.err;
  EXPECT_NE(empty.err.find("--preset : expected a preset name"), std::string::npos) << empty.err;
}

}  // namespace
}  // namespace sparseloop::test
