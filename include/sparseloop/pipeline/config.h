#pragma once
// JSON configuration of the whole pipeline (detector, search area, matching, verification, pose
// graph). Strict: an unknown key, a wrong type or an invalid value is an error naming the file and
// the key, so a typo never silently falls back to a default. Every key is optional. Each key is
// registered once (ConfigKeys() in config.cc): reading, writing, `sparseloop config --dump` and
// the table of docs/FORMATS.md ("Configuration") all come from that list. Example:
//   {"detector": {"features": {"max_features": 50, "ranking": "response"},
//                 "search": {"strategy": "paper", "drift_rate": 0.05},
//                 "check_every": 1},
//    "optimizer": {"rejection": "pcm", "loop_loss": "cauchy"}}
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sparseloop/pipeline/pipeline.h"

namespace sparseloop {

// What a configuration value should have been ("an integer", "one of a|b") and what it was.
struct ConfigValueError {
  std::string expected;
  std::string got;
};

// One configuration key: its dotted path in the JSON tree, what it holds and how to read and write
// it on PipelineOptions. The value bounds are those of the options' Check(), stated in `help`.
struct ConfigKey {
  std::string path;                  // e.g. "detector.local_map.window"
  std::string type;                  // "boolean", "integer", "number", "string", "[x, y, z]"
  std::string unit;                  // e.g. "keyframes", "px", "deg"; empty when unitless
  std::string help;                  // one line, with the bounds
  std::vector<std::string> choices;  // the accepted names of an enum key (type "string")
  // The value as JSON; null when unset (only detector.search.plane_normal can be).
  std::function<nlohmann::json(const PipelineOptions&)> get;
  // Sets the value; throws ConfigValueError when the JSON value does not fit.
  std::function<void(const nlohmann::json&, PipelineOptions*)> set;
  // "keyframes each side ... (>= 0) [keyframes]": help, unit and choices on one line.
  std::string Doc() const;
};

// Every configuration key, in documentation order (built once).
const std::vector<ConfigKey>& ConfigKeys();

// Applies the keys of `config` on top of `options`. Throws FileError(source, 0, ...) naming the
// offending key path (e.g. "detector.features.max_features") on an unknown key or wrong type, and
// std::invalid_argument from Check() on an invalid value.
void ApplyConfig(const nlohmann::json& config, const std::string& source, PipelineOptions* options);

// One key set from the text a command line gives (`--set detector.features.max_features=15`): the
// text is read as JSON when it parses as JSON (numbers, true / false, [x, y, z], "quoted"), else
// as a string, so enum names need no quotes (`--set optimizer.rejection=pcm`). Only the key is
// applied; the caller checks the whole options afterwards. Throws std::invalid_argument
// "KEY: expected ..., got ..." for an unknown key (naming the closest known keys) or a value that
// does not fit the key's type.
void ApplyConfigOverride(const std::string& key, const std::string& value,
                         PipelineOptions* options);

// Deepest nesting of objects and arrays a configuration may have (ours is 5 deep): deeper text is
// refused before it is parsed (200000 levels took the parser > 30 s and memory quadratic in the
// depth).
inline constexpr int kMaxConfigJsonDepth = 64;

// Throws std::invalid_argument "SOURCE:LINE: expected JSON nested at most 64 deep, got a 65th
// level at column C" when `text` nests objects / arrays deeper than kMaxConfigJsonDepth (FileError
// with the same line when `source_is_file`). Strings are skipped, so brackets inside them do not
// count.
void CheckJsonNesting(const std::string& text, const std::string& source, bool source_is_file);

// Reads a JSON file and applies it (FileError with line on a JSON syntax error, or nesting deeper
// than kMaxConfigJsonDepth).
void LoadConfigFile(const std::filesystem::path& path, PipelineOptions* options);

// Shipped presets: named configurations a user picks on purpose (`--preset NAME`, Python
// `preset=`, the ROS node's `~preset`), applied before any --config / --set. Their source is
// presets/NAME.json, embedded at build time and installed to share/sparseloop/presets; a root
// "doc" object says what each is for (docs/FORMATS.md, "Presets").
//   sparse: the paper's design at K = 20 (about 800 B per keyframe).
//   dense:  K = 300 (about 11 KB per keyframe).
std::vector<std::string> PresetNames();
// The preset's JSON, as in its file. Throws std::invalid_argument "expected a preset name (dense |
// sparse), got 'x'" for an unknown name.
nlohmann::json PresetConfig(const std::string& name);
// ApplyConfig(PresetConfig(name)) on top of `options`.
void ApplyPreset(const std::string& name, PipelineOptions* options);

// The full effective configuration (every key), for summary.json.
nlohmann::json ConfigToJson(const PipelineOptions& options);

// `sparseloop config --dump`: ConfigToJson(options) restricted to the keys under `scope` ("" =
// all, "detector" = the detector object), plus a root "doc": {path: ConfigKey::Doc()} for those
// keys. ApplyConfig reads it back unchanged (it ignores a root "doc" object).
nlohmann::json DumpConfig(const PipelineOptions& options, const std::string& scope);

}  // namespace sparseloop
