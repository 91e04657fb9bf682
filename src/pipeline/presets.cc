#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "presets_data.h"
#include "sparseloop/pipeline/config.h"

namespace sparseloop {

std::vector<std::string> PresetNames() {
  std::vector<std::string> names;
  for (const auto& [name, text] : pipeline_internal::kPresets) names.emplace_back(name);
  std::sort(names.begin(), names.end());
  return names;
}

nlohmann::json PresetConfig(const std::string& name) {
  for (const auto& [preset, text] : pipeline_internal::kPresets) {
    if (preset == name) return nlohmann::json::parse(text);
  }
  throw std::invalid_argument(
      fmt::format("expected a preset name ({}), got '{}'", fmt::join(PresetNames(), " | "), name));
}

void ApplyPreset(const std::string& name, PipelineOptions* options) {
  ApplyConfig(PresetConfig(name), "preset " + name, options);
}

}  // namespace sparseloop
