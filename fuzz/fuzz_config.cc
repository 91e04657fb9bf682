// Fuzzes the JSON pipeline configuration reader (syntax, unknown keys, types, values).
#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/pipeline/config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sparseloop::fuzz::WriteInput(data, size, "config.json");
  sparseloop::PipelineOptions options;
  try {
    sparseloop::LoadConfigFile(path, &options);
  } catch (const sparseloop::Error&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
