#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/cli_runner.h"
#include "sparseloop/pipeline/config.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

// `config --dump [detect|run]`: the keys each command reads with their defaults and one doc line
// each; `--config` takes the dump back (here `detect` with -K overriding nothing else).
TEST(CliConfig, DumpIsTheDefaultsWithADocPerKeyAndReadsBack) {
  const CliResult run = RunCli({"config", "--dump"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json all = nlohmann::json::parse(run.out);
  EXPECT_EQ(all["doc"].size(), ConfigKeys().size());
  EXPECT_EQ(all["doc"]["detector.local_map.window"],
            "keyframes each side of the match whose points enter the local map (>= 0) "
            "[keyframes]");
  EXPECT_EQ(all["detector"]["local_map"]["window"], 2);
  EXPECT_EQ(nlohmann::json::parse(RunCli({"config", "--dump", "run"}).out), all);

  const CliResult detect = RunCli({"config", "--dump", "detect"});
  ASSERT_EQ(detect.exit_code, 0) << detect.err;
  const nlohmann::json d = nlohmann::json::parse(detect.out);
  EXPECT_EQ(d.size(), 2u);  // "detector" and "doc"
  EXPECT_EQ(d["detector"], all["detector"]);

  const auto dir = TempDir();
  std::ofstream(dir / "run.json") << run.out;
  PipelineOptions read;
  LoadConfigFile(dir / "run.json", &read);
  EXPECT_EQ(ConfigToJson(read), ConfigToJson(PipelineOptions{}));

  EXPECT_EQ(RunCli({"config", "--dump", "optimize"}).exit_code, 2);
  EXPECT_EQ(RunCli({"config"}).exit_code, 2);  // --dump is the only action
}

// A dumped file is accepted by `detect --config` on a real sequence (and gives the same loops as
// no --config at all: the dump is the defaults).
TEST(CliConfig, DetectAcceptsTheDump) {
  const auto dir = TempDir();
  std::ofstream(dir / "detect.json") << RunCli({"config", "--dump", "detect"}).out;
  const auto& seq = RenderedLoopSequence();
  const CliResult with = RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--poses",
                                 (seq / "poses_raw.txt").string(), "--config",
                                 (dir / "detect.json").string(), "--out", (dir / "a").string()});
  ASSERT_EQ(with.exit_code, 0) << with.err;
  const CliResult without =
      RunCli({"detect", "--dataset", "kitti:" + seq.string(), "--poses",
              (seq / "poses_raw.txt").string(), "--out", (dir / "b").string()});
  ASSERT_EQ(without.exit_code, 0) << without.err;
  std::ifstream a(dir / "a" / "loops.csv"), b(dir / "b" / "loops.csv");
  std::stringstream sa, sb;
  sa << a.rdbuf();
  sb << b.rdbuf();
  EXPECT_EQ(sa.str(), sb.str());
}

}  // namespace
}  // namespace sparseloop::test
