// Fuzzes the JSON pipeline configuration reader (syntax, unknown keys, types, values). Beyond "no
// crash, only FileError / invalid_argument": a file the reader accepts holds no key twice in one
// object (checked here by an independent SAX pass: JSON allows repeats, the reader must not).
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/pipeline/config.h"

namespace {

// True when some object of `text` (valid JSON) repeats a key.
struct DuplicateKeyFinder : nlohmann::json_sax<nlohmann::json> {
  std::vector<std::set<std::string>> objects;
  bool found = false;
  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override {
    objects.emplace_back();
    return true;
  }
  bool key(string_t& k) override {
    if (!objects.empty() && !objects.back().insert(k).second) found = true;
    return true;
  }
  bool end_object() override {
    objects.pop_back();
    return true;
  }
  bool start_array(std::size_t) override { return true; }
  bool end_array() override { return true; }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sparseloop::fuzz::WriteInput(data, size, "config.json");
  sparseloop::PipelineOptions options;
  try {
    sparseloop::LoadConfigFile(path, &options);
  } catch (const sparseloop::Error&) {
    return 0;
  } catch (const std::invalid_argument&) {
    return 0;
  }
  DuplicateKeyFinder finder;
  const std::string text(reinterpret_cast<const char*>(data), size);
  nlohmann::json::sax_parse(text, &finder, nlohmann::json::input_format_t::json, false);
  if (finder.found) __builtin_trap();
  return 0;
}
