#pragma once
// Internal to io: the small YAML subset of EuRoC/Kalibr sensor.yaml files ("key: value",
// "key: [a, b, ...]" lists possibly spanning lines, one level of indented "parent: / child:" keys
// read as "parent.child", '#' comments). Errors throw FileError with the file and line.
#include <map>
#include <string>
#include <vector>

#include "io/text_parsing.h"

namespace sparseloop::io_internal {

struct YamlValue {
  std::string text;  // scalar, or "[...]" for a list
  int line = 0;
};

// Every key of the file with its value text and line (nested keys as "parent.key").
std::map<std::string, YamlValue> ParseYamlSubset(const TextFile& file);
// The numbers of the list value of `key` ("[a, b, ...]"); FileError naming `file` when the key is
// missing, the value is not a list, or an element is not a finite number.
std::vector<double> YamlNumbers(const std::map<std::string, YamlValue>& yaml,
                                const std::string& key, const std::string& file);

}  // namespace sparseloop::io_internal
