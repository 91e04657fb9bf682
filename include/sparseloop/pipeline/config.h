#pragma once
// JSON configuration of the whole pipeline (detector, search area, matching, verification, pose
// graph). Strict: an unknown key, a wrong type or an invalid value is an error naming the file and
// the key, so a typo never silently falls back to a default. Every key is optional; see
// docs/FORMATS.md ("Configuration") for the list. Example:
//   {"detector": {"features": {"max_features": 50, "ranking": "response"},
//                 "search": {"strategy": "paper", "drift_tolerance": 0.02},
//                 "check_every": 1},
//    "optimizer": {"rejection": "pcm", "loop_loss": "cauchy"}}
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "sparseloop/pipeline/pipeline.h"

namespace sparseloop {

// Applies the keys of `config` on top of `options`. Throws FileError(source, 0, ...) naming the
// offending key path (e.g. "detector.features.max_features") on an unknown key or wrong type, and
// std::invalid_argument from Check() on an invalid value.
void ApplyConfig(const nlohmann::json& config, const std::string& source, PipelineOptions* options);

// Reads a JSON file and applies it (FileError with line on a JSON syntax error).
void LoadConfigFile(const std::filesystem::path& path, PipelineOptions* options);

// The full effective configuration (every key), for summary.json and --print-config.
nlohmann::json ConfigToJson(const PipelineOptions& options);

}  // namespace sparseloop
