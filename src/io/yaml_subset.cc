// The YAML subset reader of yaml_subset.h (EuRoC/Kalibr sensor.yaml).
#include "io/yaml_subset.h"

#include <string_view>

#include <fmt/format.h>

#include "sparseloop/core/error.h"

namespace sparseloop::io_internal {

std::map<std::string, YamlValue> ParseYamlSubset(const TextFile& file) {
  std::map<std::string, YamlValue> out;
  std::string parent;
  std::string open_key;  // key of a list still missing its ']'
  for (const auto& line : file.lines()) {
    std::string_view text = line.text;
    if (const size_t hash = text.find('#'); hash != std::string_view::npos) {
      text = text.substr(0, hash);
    }
    if (Trim(text).empty()) continue;
    if (!open_key.empty()) {
      if (text.find(':') != std::string_view::npos) {  // a new key: the list was never closed
        throw FileError(file.name(), out[open_key].line,
                        fmt::format("a closing ']' for {}", open_key),
                        fmt::format("a new key on line {}", line.number));
      }
      out[open_key].text += " " + std::string(Trim(text));
      if (text.find(']') != std::string_view::npos) open_key.clear();
      continue;
    }
    const std::string_view trimmed = Trim(text);
    if (trimmed.front() == '%' || trimmed.substr(0, 3) == "---") continue;
    const size_t colon = trimmed.find(':');
    if (colon == std::string_view::npos) {
      throw FileError(file.name(), line.number, "'key: value'", Quote(trimmed));
    }
    const std::string key(Trim(trimmed.substr(0, colon)));
    const std::string value(Trim(trimmed.substr(colon + 1)));
    const bool indented = text.front() == ' ' || text.front() == '\t';
    std::string full_key = key;
    if (indented && !parent.empty()) {
      full_key = parent + "." + key;
    } else {
      parent = key;
    }
    out[full_key] = YamlValue{value, line.number};
    if (!value.empty() && value.front() == '[' && value.find(']') == std::string::npos) {
      open_key = full_key;
    }
  }
  if (!open_key.empty()) {
    throw FileError(file.name(), out[open_key].line, fmt::format("a closing ']' for {}", open_key),
                    "end of file");
  }
  return out;
}

std::vector<double> YamlNumbers(const std::map<std::string, YamlValue>& yaml,
                                const std::string& key, const std::string& file) {
  const auto it = yaml.find(key);
  if (it == yaml.end()) throw FileError(file, 0, fmt::format("a '{}:' entry", key), "none");
  std::string_view text = Trim(it->second.text);
  if (text.size() < 2 || text.front() != '[' || text.back() != ']') {
    throw FileError(file, it->second.line, fmt::format("a list [a, b, ...] for {}", key),
                    Quote(text));
  }
  text = Trim(text.substr(1, text.size() - 2));
  std::vector<double> out;
  if (text.empty()) return out;
  for (auto token : SplitComma(text)) {
    out.push_back(ParseDouble(token, file, it->second.line, key));
  }
  return out;
}

}  // namespace sparseloop::io_internal
