// Fuzzes the EuRoC sensor.yaml reader (intrinsics, distortion, T_BS).
#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/dataset.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sparseloop::fuzz::WriteInput(data, size, "sensor.yaml");
  try {
    sparseloop::ReadEurocSensorYaml(path);
  } catch (const sparseloop::Error&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
