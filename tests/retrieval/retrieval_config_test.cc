// JSON configuration of the candidate retrieval (detector.retrieval, detector.ann) and the two
// baseline configuration files in bench/configs.
#include <gtest/gtest.h>

#include "sparseloop/core/error.h"
#include "sparseloop/pipeline/config.h"
#include "test_util.h"

namespace sparseloop {
namespace {

std::string ErrorOf(const std::string& text) {
  PipelineOptions o;
  try {
    ApplyConfig(nlohmann::json::parse(text), "cfg.json", &o);
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

TEST(RetrievalConfig, RoundTripOfTheNewKeys) {
  PipelineOptions o;
  ApplyConfig(
      nlohmann::json::parse(R"({"detector": {"retrieval": "ann", "ann": {"max_candidates": 7}}})"),
      "cfg.json", &o);
  EXPECT_EQ(o.detector.retrieval, CandidateRetrieval::kAnn);
  EXPECT_EQ(o.detector.ann.max_candidates, 7);
  // The index's own parameters are the library's (AnnOptions), not configuration keys.
  EXPECT_NE(ErrorOf(R"({"detector": {"ann": {"hnsw_m": 8}}})").find("detector.ann.hnsw_m"),
            std::string::npos);
  // Written back and read again: the same options.
  const nlohmann::json j = ConfigToJson(o);
  EXPECT_EQ(j["detector"]["retrieval"], "ann");
  EXPECT_EQ(j["detector"]["ann"]["max_candidates"], 7);
  PipelineOptions again;
  ApplyConfig(j, "again.json", &again);
  EXPECT_EQ(ConfigToJson(again), j);
  EXPECT_EQ(again.detector.retrieval, CandidateRetrieval::kAnn);
  // The default is brute force.
  EXPECT_EQ(ConfigToJson(PipelineOptions{})["detector"]["retrieval"], "brute_force");
}

TEST(RetrievalConfig, RejectsUnknownAndInvalid) {
  EXPECT_NE(ErrorOf(R"({"detector": {"retrieval": "hnsw"}})").find("detector.retrieval"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"detector": {"ann": {"efsearch": 3}}})").find("detector.ann.efsearch"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"detector": {"ann": {"max_candidates": 2.5}}})")
                .find("detector.ann.max_candidates"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"detector": {"ann": {"max_candidates": 0}}})"), "");
}

// bench/configs/full_global.json, full_global_24.json and full_ann.json: parse strictly and mean
// what they say (docs/BENCHMARKS.md, "Baselines").
TEST(RetrievalConfig, BaselineConfigFiles) {
  const auto dir = test::SourceDir() / "bench" / "configs";
  for (const char* name : {"full_global.json", "full_global_24.json", "full_ann.json"}) {
    SCOPED_TRACE(name);
    PipelineOptions o;
    LoadConfigFile(dir / name, &o);
    const LoopDetector::Options& d = o.detector;
    EXPECT_EQ(d.features.max_features, 1000);
    EXPECT_EQ(d.features.orb_candidates, 1000);
    EXPECT_FALSE(d.features.use_gradient_mask);
    EXPECT_EQ(d.search.strategy, SearchStrategy::kGlobal);
    EXPECT_FALSE(d.check_consistency);
    EXPECT_EQ(d.min_path_ratio, 0.0);
    // A classic detector's temporal window: the 50 most recent keyframes are no candidates.
    EXPECT_EQ(d.search.exclude_recent, 50);
    // The same verification as sparseloop's defaults; full_global_24 only lowers the inlier
    // threshold to the absolute value sparseloop's default K gets (24).
    const LoopDetector::Options defaults;
    EXPECT_EQ(d.min_matches, defaults.min_matches);
    EXPECT_EQ(d.max_verify, defaults.max_verify);
    if (std::string(name) == "full_global_24.json") {
      EXPECT_EQ(d.EffectiveMinInliers(), defaults.EffectiveMinInliers());
      EXPECT_EQ(d.EffectiveMinInliers(), 24);
    } else {
      EXPECT_EQ(d.min_inlier_fraction_of_k, defaults.min_inlier_fraction_of_k);
      EXPECT_EQ(d.EffectiveMinInliers(), 80);
    }
    EXPECT_EQ(d.verify.min_inliers, defaults.verify.min_inliers);
    EXPECT_EQ(d.verify.threshold_px, defaults.verify.threshold_px);
    EXPECT_EQ(d.retrieval, std::string(name) == "full_ann.json" ? CandidateRetrieval::kAnn
                                                                : CandidateRetrieval::kBruteForce);
  }
}

}  // namespace
}  // namespace sparseloop
