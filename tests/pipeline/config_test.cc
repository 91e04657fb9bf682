#include "sparseloop/pipeline/config.h"

#include "sparseloop/core/error.h"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <regex>
#include <sstream>

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
                   "check_every": 5, "seed": 7, "best_of_verified": false,
                   "min_path_ratio": 2.5},
      "optimizer": {"rejection": "none", "loop_loss": "huber", "loop_weight_rounds": 2,
                    "num_threads": 3},
      "vertex_type": "se3"})"),
              "cfg.json", &o);
  EXPECT_EQ(o.detector.features.max_features, 15);
  EXPECT_EQ(o.detector.features.ranking, FeatureRanking::kPopcount);
  EXPECT_EQ(o.detector.search.strategy, SearchStrategy::kRadius);
  EXPECT_DOUBLE_EQ(o.detector.search.radius, 7.5);
  ASSERT_TRUE(o.detector.search.plane_normal.has_value());
  EXPECT_EQ(*o.detector.search.plane_normal, Eigen::Vector3d(0, 1, 0));
  EXPECT_EQ(o.detector.check_every, 5);
  EXPECT_FALSE(o.detector.best_of_verified);
  EXPECT_DOUBLE_EQ(o.detector.min_path_ratio, 2.5);
  EXPECT_EQ(o.detector.verify.seed, 7u);
  EXPECT_EQ(o.optimizer.rejection, OutlierRejection::kNone);
  EXPECT_EQ(o.optimizer.loop_loss, RobustLoss::kHuber);
  EXPECT_EQ(o.optimizer.loop_weight_rounds, 2);
  EXPECT_EQ(o.optimizer.num_threads, 3);
  EXPECT_EQ(o.vertex_type, VertexType::kSe3);
}

TEST(Config, RoundTripsThroughJson) {
  PipelineOptions a;
  a.detector.features.max_features = 23;
  a.detector.search.drift_rate = 0.03;
  a.optimizer.rejection = OutlierRejection::kNone;
  a.optimizer.loop_weight_rounds = 1;
  a.optimizer.num_threads = 2;
  a.detector.best_of_verified = false;
  a.detector.min_path_ratio = 1.5;
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
                .find("a valid value for \"detector.features.max_features\""),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"min_inlier_fraction_of_k": 1.5}})"))
                .find("min_inlier_fraction_of_k must be in [0, 1]"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"search": {"plane_normal": [1, 2]}}})"))
                .find("an array of 3 numbers"),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"([1, 2])")).find("a JSON object"), std::string::npos);
}

// A value that fails its check names the key by its whole path: four keys end in
// rotation_sigma_rad, and the check's own message names the last part only.
TEST(Config, ABadValueNamesItsWholeKeyPath) {
  const std::string e = ErrorOf(nlohmann::json::parse(
      R"({"odometry": {"rotation_sigma_rad": 0.02}, "direction_loop": {"rotation_sigma_rad": 0}})"));
  EXPECT_NE(e.find("a valid value for \"direction_loop.rotation_sigma_rad\""), std::string::npos)
      << e;
  EXPECT_NE(e.find("rotation_sigma_rad must be > 0"), std::string::npos) << e;
  const std::string o =
      ErrorOf(nlohmann::json::parse(R"({"odometry": {"rotation_sigma_rad": -1}})"));
  EXPECT_NE(o.find("\"odometry.rotation_sigma_rad\""), std::string::npos) << o;
}

// JSON allows a key twice in an object and the parser keeps the last value; a strict reader
// refuses it, naming the dotted key and the line of the repeat (CR-only line ends counted too).
TEST(Config, DuplicateKeysAndFoldersAreFileErrors) {
  const auto dir = test::TempDir();
  const auto expect = [&](const std::string& text, int line, const std::string& got) {
    std::ofstream(dir / "c.json", std::ios::binary) << text;
    try {
      PipelineOptions o;
      LoadConfigFile(dir / "c.json", &o);
      ADD_FAILURE() << "no FileError for " << text;
    } catch (const FileError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_NE(e.got().find(got), std::string::npos) << e.what();
    }
  };
  expect("{\"detector\": {\"check_every\": 1,\n \"check_every\": 2}}", 2,
         "\"detector.check_every\" a second time");
  expect("{\"optimizer\": {},\r\"detector\": {},\r\"optimizer\": {}}", 3,
         "\"optimizer\" a second time");
  expect(
      "{\"detector\": {\"features\": {\"max_features\": 15}},\n"
      " \"detector\": {\"features\": {\"max_features\": 20}}}",
      2, "\"detector\" a second time");
  // Same key names in different objects are fine.
  std::ofstream(dir / "ok.json") << R"({"odometry": {"rotation_sigma_rad": 0.02},
      "direction_loop": {"rotation_sigma_rad": 0.1}})";
  PipelineOptions o;
  EXPECT_NO_THROW(LoadConfigFile(dir / "ok.json", &o));
  EXPECT_DOUBLE_EQ(o.direction_loop.rotation_sigma_rad, 0.1);
  try {
    LoadConfigFile(dir, &o);
    ADD_FAILURE() << "a folder read as a config";
  } catch (const FileError& e) {
    EXPECT_EQ(e.got(), "a directory") << e.what();
  }
}

// The bounds `config --dump` states for a key are the bounds its Check() applies: a value on a
// stated bound is accepted and one just outside refused ("(>= 1)" for a key checked in [5, 10000]
// told users K = 1 was fine).
TEST(Config, DocumentedBoundsAreTheCheckedBounds) {
  const std::regex range(R"(([\[(])(-?[0-9.e+-]+), (-?[0-9.e+-]+)([\])]))");
  const std::regex at_least(R"((>=|>) (-?[0-9.e+-]+)\))");
  const auto accepted = [](const ConfigKey& key, double value) {
    // The keys a bound of another key depends on, at their widest: K <= orb_candidates,
    // ann.neighbors <= ann.ef_search.
    PipelineOptions o;
    o.detector.features.orb_candidates = 10000;
    o.detector.ann.ef_search = 4096;
    try {
      key.set(key.type == "integer" ? nlohmann::json(static_cast<int64_t>(value))
                                    : nlohmann::json(value),
              &o);
      o.Check();
    } catch (const std::exception&) {
      return false;
    } catch (const ConfigValueError&) {
      return false;
    }
    return true;
  };
  int checked = 0;
  for (const ConfigKey& key : ConfigKeys()) {
    if (key.type != "integer" && key.type != "number") continue;
    SCOPED_TRACE(key.path + ": " + key.help);
    // Just outside a bound: the next integer, or a relative 1e-9 for a number.
    const auto step = [&](double bound) {
      return key.type == "integer" ? 1.0 : 1e-9 * std::max(1.0, std::abs(bound));
    };
    // "(0 = off, else >= 3)": 0 is a value of its own, not a value below the bound.
    const bool zero_is_off = key.help.find("0 = off") != std::string::npos;
    const auto refused_below = [&](double lo) {
      const double outside = lo - step(lo);
      if (zero_is_off && outside == 0.0) return;
      EXPECT_FALSE(accepted(key, outside)) << outside;
    };
    std::smatch m;
    if (std::regex_search(key.help, m, range)) {
      const double lo = std::stod(m[2]), hi = std::stod(m[3]);
      const bool lo_in = m[1] == "[", hi_in = m[4] == "]";
      EXPECT_EQ(accepted(key, lo), lo_in) << lo;
      refused_below(lo);
      EXPECT_EQ(accepted(key, hi), hi_in) << hi;
      EXPECT_FALSE(accepted(key, hi + step(hi))) << hi + step(hi);
      ++checked;
    } else if (std::regex_search(key.help, m, at_least)) {
      const double lo = std::stod(m[2]);
      EXPECT_EQ(accepted(key, lo), m[1] == ">=") << lo;
      refused_below(lo);
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
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

// Every line end counts (CR-only, CRLF, LF): the error names our line and column, never the JSON
// parser's own position ("line 1, column 49": it counts "\n" only) or its exception name.
TEST(Config, SyntaxErrorNamesOurLineAndColumnForEveryLineEnd) {
  for (const std::string end : {"\n", "\r\n", "\r"}) {
    SCOPED_TRACE(end == "\r" ? "CR" : end == "\n" ? "LF" : "CRLF");
    const auto path = test::TempDir() / "bad.json";
    std::ofstream(path, std::ios::binary)
        << "{" << end << "  \"detector\": {" << end << "    \"check_every\": 3," << end << "  }"
        << end << "}" << end;
    try {
      PipelineOptions o;
      LoadConfigFile(path, &o);
      ADD_FAILURE() << "no throw";
    } catch (const FileError& e) {
      const std::string what = e.what();
      EXPECT_EQ(e.line(), 4) << what;
      EXPECT_NE(what.find(path.string() + ":4: expected valid JSON at column 3, got "),
                std::string::npos)
          << what;
      EXPECT_EQ(what.find("line 1"), std::string::npos) << what;
      EXPECT_EQ(what.find("json.exception"), std::string::npos) << what;
    }
  }
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

// A 1.2 MB configuration {"x": {"a":{"a":...}}} 200000 deep ran > 30 s (memory quadratic in the
// depth): nesting deeper than kMaxConfigJsonDepth is refused before parsing, with our line and
// column; brackets inside strings do not count.
TEST(Config, DeepNestingIsRefusedBeforeParsing) {
  const auto path = test::TempDir() / "deep.json";
  {
    std::ofstream out(path);
    out << "{\n\"x\": ";
    for (int i = 0; i < 200000; ++i) out << "{\"a\":";
    out << "1";
    for (int i = 0; i < 200000; ++i) out << "}";
    out << "}\n";
  }
  const auto start = std::chrono::steady_clock::now();
  try {
    PipelineOptions o;
    LoadConfigFile(path, &o);
    ADD_FAILURE() << "no throw";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 2) << e.what();
    // The 65th level: "x"'s object opens at column 6, each "a" adds 5 columns.
    EXPECT_NE(std::string(e.what()).find(":2: expected JSON nested at most 64 deep at column " +
                                         std::to_string(6 + 5 * 63) + ", got a level 65 deep"),
              std::string::npos)
        << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
  // 64 levels parse (and fail on the unknown key); brackets inside a string are text.
  const auto ok = test::TempDir() / "deep64.json";
  {
    std::ofstream out(ok);
    for (int i = 0; i < 64; ++i) out << "{\"a\\\"[{\":";
    out << "1";
    for (int i = 0; i < 64; ++i) out << "}";
  }
  try {
    PipelineOptions o;
    LoadConfigFile(ok, &o);
    ADD_FAILURE() << "no throw";
  } catch (const std::exception& e) {
    EXPECT_EQ(std::string(e.what()).find("nested"), std::string::npos) << e.what();
  }
  PipelineOptions o;
  EXPECT_THROW(ApplyConfigOverride("detector.check_every", std::string(65, '[') + "1", &o),
               std::invalid_argument);
}

// A value of `key` other than its default that the options' Check() accepts.
nlohmann::json OtherValue(const ConfigKey& key, const nlohmann::json& current) {
  if (!key.choices.empty()) {
    return key.choices[0] == current.get<std::string>() ? key.choices[1] : key.choices[0];
  }
  if (current.is_null()) return {0.0, 0.0, 1.0};  // plane_normal
  if (current.is_boolean()) return !current.get<bool>();
  if (current.is_number_integer()) return current.get<int64_t>() + 1;
  const double d = current.get<double>();
  return d == 0.0 ? 0.5 : 0.9 * d;
}

// Every registered key is read by ApplyConfig and written back by ConfigToJson, at its path.
TEST(Config, EveryRegisteredKeyIsReadAndWritten) {
  const nlohmann::json defaults = ConfigToJson(PipelineOptions{});
  ASSERT_GT(ConfigKeys().size(), 50u);
  for (const ConfigKey& key : ConfigKeys()) {
    SCOPED_TRACE(key.path);
    const auto pointer =
        nlohmann::json::json_pointer("/" + std::regex_replace(key.path, std::regex(R"(\.)"), "/"));
    const nlohmann::json before = defaults.contains(pointer) ? defaults[pointer] : nlohmann::json();
    EXPECT_EQ(before.is_null(), key.path == "detector.search.plane_normal");
    nlohmann::json config;
    config[pointer] = OtherValue(key, before);
    PipelineOptions o;
    ASSERT_NO_THROW(ApplyConfig(config, "cfg.json", &o)) << config.dump();
    EXPECT_EQ(key.get(o), config[pointer]);
    EXPECT_EQ(ConfigToJson(o)[pointer], config[pointer]);
    EXPECT_FALSE(key.help.empty());
  }
}

// `--set KEY=VALUE` (ApplyConfigOverride) reaches every registered key: another valid value, given
// as the text a shell passes (JSON, or a bare word for enum names), is what the key then holds.
TEST(Config, EveryRegisteredKeyCanBeSetFromText) {
  const nlohmann::json defaults = ConfigToJson(PipelineOptions{});
  for (const ConfigKey& key : ConfigKeys()) {
    SCOPED_TRACE(key.path);
    const auto pointer =
        nlohmann::json::json_pointer("/" + std::regex_replace(key.path, std::regex(R"(\.)"), "/"));
    const nlohmann::json before = defaults.contains(pointer) ? defaults[pointer] : nlohmann::json();
    const nlohmann::json other = OtherValue(key, before);
    const std::string text = other.is_string() ? other.get<std::string>() : other.dump();
    PipelineOptions o;
    ASSERT_NO_THROW(ApplyConfigOverride(key.path, text, &o)) << text;
    EXPECT_EQ(key.get(o), other) << text;
  }
}

TEST(Config, OverrideErrorsNameTheKeyAndWhatFits) {
  PipelineOptions o;
  auto message = [&](const std::string& key, const std::string& value) {
    try {
      ApplyConfigOverride(key, value, &o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string unknown = message("detector.features.max_feature", "15");
  EXPECT_NE(unknown.find("detector.features.max_feature: expected a configuration key"),
            std::string::npos)
      << unknown;
  EXPECT_NE(unknown.find("detector.features.max_features"), std::string::npos) << unknown;
  EXPECT_NE(message("max_features", "15").find("such as detector.features.max_features"),
            std::string::npos);
  const std::string type = message("detector.features.max_features", "many");
  EXPECT_NE(type.find("expected an integer"), std::string::npos) << type;
  const std::string name = message("optimizer.rejection", "pcmm");
  EXPECT_NE(name.find("optimizer.rejection: expected"), std::string::npos) << name;
  EXPECT_NE(name.find("pcm"), std::string::npos) << name;
  // Quoted and bare strings are the same value.
  ApplyConfigOverride("optimizer.rejection", "\"none\"", &o);
  EXPECT_EQ(o.optimizer.rejection, OutlierRejection::kNone);
  ApplyConfigOverride("optimizer.rejection", "pcm", &o);
  EXPECT_EQ(o.optimizer.rejection, OutlierRejection::kPcm);
}

// `config --dump`: the defaults plus a "doc" line per key; read back unchanged, from a file too.
TEST(Config, DumpRoundTripsAndDocumentsEveryKey) {
  const PipelineOptions defaults;
  const nlohmann::json dump = DumpConfig(defaults, "");
  EXPECT_EQ(dump["doc"].size(), ConfigKeys().size());
  for (const ConfigKey& key : ConfigKeys()) EXPECT_EQ(dump["doc"][key.path], key.Doc());
  const auto path = test::TempDir() / "dump.json";
  std::ofstream(path) << dump.dump(2);
  PipelineOptions read;
  read.detector.check_every = 9;
  LoadConfigFile(path, &read);
  EXPECT_EQ(ConfigToJson(read), ConfigToJson(defaults));
  nlohmann::json without_doc = dump;
  without_doc.erase("doc");
  EXPECT_EQ(without_doc, ConfigToJson(defaults));

  // detect's dump: the detector object only, read back the same way.
  const nlohmann::json detect = DumpConfig(defaults, "detector");
  EXPECT_EQ(detect.size(), 2u);  // "detector", "doc"
  EXPECT_EQ(detect["detector"], ConfigToJson(defaults)["detector"]);
  for (const auto& [path, doc] : detect["doc"].items()) EXPECT_EQ(path.rfind("detector.", 0), 0u);
  PipelineOptions detect_read;
  ApplyConfig(detect, "detect.json", &detect_read);
  EXPECT_EQ(ConfigToJson(detect_read), ConfigToJson(defaults));
}

TEST(Config, UnknownKeysAreRefusedAtEveryLevel) {
  for (const char* text :
       {R"({"detectr": {}})", R"({"detector": {"local_map": {"windw": 1}}})",
        R"({"optimizer": {"pcm": {"confidence": 0.9}}})", R"({"detector": {"doc": {}}})"}) {
    SCOPED_TRACE(text);
    EXPECT_NE(ErrorOf(nlohmann::json::parse(text)).find("a known configuration key"),
              std::string::npos);
  }
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"local_map": 3}})"))
                .find("a JSON object for \"detector.local_map\""),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"doc": 3})")).find("a JSON object for \"doc\""),
            std::string::npos);
  EXPECT_NE(ErrorOf(nlohmann::json::parse(R"({"detector": {"check_every": 4294967297}})"))
                .find("an integer in"),
            std::string::npos);
  EXPECT_EQ(ErrorOf(nlohmann::json::parse(R"({"doc": {"anything": "ignored"}})")), "");
}

// docs/FORMATS.md ("Configuration") has one row per registered key with its default and doc, so
// the table cannot go stale (regenerate it from `sparseloop config --dump`).
TEST(Config, FormatsDocListsEveryKey) {
  std::ifstream in(test::SourceDir() / "docs" / "FORMATS.md");
  std::stringstream text;
  text << in.rdbuf();
  for (const ConfigKey& key : ConfigKeys()) {
    const nlohmann::json value = key.get(PipelineOptions{});
    const std::string row = "| `" + key.path + "` | `" +
                            (value.is_null() ? "unset" : value.dump()) + "` | " +
                            std::regex_replace(key.Doc(), std::regex(R"(\|)"), R"(\|)") + " |\n";
    EXPECT_NE(text.str().find(row), std::string::npos)
        << "docs/FORMATS.md lacks the row\n"
        << row << "(table: sparseloop config --dump)";
  }
  // And no row of a key that is gone.
  const std::regex table_row(R"(\| `([a-z_.0-9]+)` \| `[^`]*` \| .*\|)");
  const std::string doc = text.str();
  for (std::sregex_iterator it(doc.begin(), doc.end(), table_row), end; it != end; ++it) {
    const std::string path = (*it)[1];
    EXPECT_TRUE(std::any_of(ConfigKeys().begin(), ConfigKeys().end(),
                            [&](const ConfigKey& key) { return key.path == path; }))
        << "docs/FORMATS.md has a row for \"" << path << "\", which is no configuration key";
  }
}

// The configuration is what a user tunes, each key with a reason in its doc; the estimators'
// and the graph's inner constants are the library's options (LoopDetector::Options and the
// structs it holds), not keys.
TEST(Config, AtMostAHundredKeysEachWithADoc) {
  EXPECT_LE(ConfigKeys().size(), 100u);
  for (const ConfigKey& key : ConfigKeys()) EXPECT_GE(key.help.size(), 12u) << key.path;
}

}  // namespace
}  // namespace sparseloop

namespace sparseloop {
namespace {

// The embedded presets are the files presets/NAME.json (one source, installed beside the binary
// to share/sparseloop/presets), each with a doc line naming it, each a valid configuration.
TEST(Presets, EmbeddedAreTheShippedFilesAndEachIsValid) {
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(test::SourceDir() / "presets"))
    if (entry.path().extension() == ".json") files.push_back(entry.path().stem().string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(PresetNames(), files);
  for (const std::string& name : PresetNames()) {
    SCOPED_TRACE(name);
    std::ifstream in(test::SourceDir() / "presets" / (name + ".json"));
    EXPECT_EQ(PresetConfig(name), nlohmann::json::parse(in));
    const std::string doc = PresetConfig(name)["doc"]["preset"].get<std::string>();
    EXPECT_EQ(doc.rfind(name + ": ", 0), 0u) << doc;
    PipelineOptions options;
    ApplyPreset(name, &options);
    EXPECT_NO_THROW(options.Check());
  }
}

// sparse is the paper's design at K = 20; dense is K = 300; neither changes anything else from
// the defaults, and an unknown name lists the shipped ones.
TEST(Presets, WhatEachSetsAndAnUnknownName) {
  PipelineOptions sparse;
  ApplyPreset("sparse", &sparse);
  EXPECT_EQ(sparse.detector.features.max_features, 20);
  EXPECT_TRUE(sparse.detector.asymmetric_matching);
  EXPECT_TRUE(sparse.detector.weak_pairs);
  EXPECT_EQ(sparse.detector.repeatability_window, 4);
  EXPECT_TRUE(sparse.detector.appearance_fallback);
  PipelineOptions dense;
  ApplyPreset("dense", &dense);
  EXPECT_EQ(dense.detector.features.max_features, 300);
  const nlohmann::json defaults = ConfigToJson(PipelineOptions{});
  nlohmann::json dense_json = ConfigToJson(dense);
  dense_json["detector"]["features"]["max_features"] =
      defaults["detector"]["features"]["max_features"];
  EXPECT_EQ(dense_json, defaults);
  PipelineOptions untouched;
  try {
    ApplyPreset("tiny", &untouched);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "expected a preset name (dense | sparse), got 'tiny'");
  }
}

}  // namespace
}  // namespace sparseloop
