#include "sparseloop/pipeline/config.h"

#include "sparseloop/core/error.h"

#include <fstream>

#include <gtest/gtest.h>

#include "test_util.h"

namespace sparseloop {
namespace {

std::string ErrorOf(const nlohmann::json& j) {
  PipelineOptions o;
  try {
    ApplyConfig(j, "cfg.json", &o);
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

TEST(Config, AppliesKnownKeys) {
  PipelineOptions o;
  ApplyConfig(nlohmann::json::parse(R"({
      "detector": {"features": {"max_features": 15, "ranking": "popcount"},
                   "search": {"strategy": "radius", "radius": 7.5, "plane_normal": [0, 1, 0]},
                   "check_every": 5, "seed": 7, "planar_alternatives": false,
                   "planar_alternative_tolerance": 0.3},
      "optimizer": {"rejection": "switchable", "loop_loss": "huber", "reduce_chains": false,
                    "max_chain_length": 3},
      "vertex_type": "se3"})"),
              "cfg.json", &o);
  EXPECT_EQ(o.detector.features.max_features, 15);
  EXPECT_EQ(o.detector.features.ranking, FeatureRanking::kPopcount);
  EXPECT_EQ(o.detector.search.strategy, SearchStrategy::kRadius);
  EXPECT_DOUBLE_EQ(o.detector.search.radius, 7.5);
  ASSERT_TRUE(o.detector.search.plane_normal.has_value());
  EXPECT_EQ(*o.detector.search.plane_normal, Eigen::Vector3d(0, 1, 0));
  EXPECT_EQ(o.detector.check_every, 5);
  EXPECT_FALSE(o.detector.planar_alternatives);
  EXPECT_DOUBLE_EQ(o.detector.planar_alternative_tolerance, 0.3);
  EXPECT_EQ(o.detector.verify.seed, 7u);
  EXPECT_EQ(o.optimizer.rejection, OutlierRejection::kSwitchable);
  EXPECT_EQ(o.optimizer.loop_loss, RobustLoss::kHuber);
  EXPECT_FALSE(o.optimizer.reduce_chains);
  EXPECT_EQ(o.optimizer.max_chain_length, 3);
  EXPECT_EQ(o.vertex_type, VertexType::kSe3);
}

TEST(Config, RoundTripsThroughJson) {
  PipelineOptions a;
  a.detector.features.max_features = 23;
  a.detector.search.drift_tolerance = 0.03;
  a.optimizer.rejection = OutlierRejection::kNone;
  a.optimizer.reduce_chains = false;
  a.optimizer.max_chain_length = 5;
  a.detector.planar_alternatives = false;
  a.detector.planar_alternative_tolerance = 0.25;
  PipelineOptions b;
  ApplyConfig(ConfigToJson(a), "roundtrip", &b);
  EXPECT_EQ(ConfigToJson(a), ConfigToJson(b));
}

TEST(Config, UnknownKeyWrongTypeAndBadValueNameTheKey) {
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"features": {"max_featurs": 3}}})"))
                .find("detector.features.max_featurs"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"check_every": "five"}})"))
                .find("an integer for \"detector.check_every\""),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"search": {"strategy": "magic"}}})"))
                .find("paper|radius|global"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"features": {"max_features": -4}}})"))
                .find("valid option values"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"planar_alternative_tolerance": 1.5}})"))
                .find("planar_alternative_tolerance must be in (0, 1]"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"search": {"plane_normal": [1, 2]}}})"))
                .find("an array of 3 numbers"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"([1, 2])")).find("a JSON object"), std::string::npos);
}

TEST(Config, SyntaxErrorNamesTheLine) {
  const auto path = test::TempDir() / "bad.json";
  std::ofstream(path) << "{\n  \"detector\": {\n    \"check_every\": 3,\n  }\n}\n";
  try {
    PipelineOptions o;
    LoadConfigFile(path, &o);
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 4) << e.what();
    EXPECT_EQ(e.file(), path.string());
  }
  PipelineOptions o;
  EXPECT_THROW(LoadConfigFile(test::TempDir() / "missing.json", &o), FileError);
}

// Found by fuzz_config: a number beyond double range is nlohmann's out_of_range, not a
// parse_error; it must still be a FileError naming the file.
TEST(Config, NumberOverflowIsAFileError) {
  const auto path = test::TempDir() / "overflow.json";
  std::ofstream(path) << "{\"detector\": {\"check_every\": 7777777777e7000000000}}\n";
  try {
    PipelineOptions o;
    LoadConfigFile(path, &o);
    FAIL() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), path.string());
    EXPECT_NE(std::string(e.what()).find("overflow"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sparseloop
