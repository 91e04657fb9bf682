// Fuzzes the KITTI sequence loader through its calib.txt: a one-image sequence whose calib.txt is
// the fuzz input.
#include <fstream>

#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/dataset.h"

namespace {
// A valid 8x4 grayscale PNG header (signature + IHDR); the loader only reads the size.
const unsigned char kPng[] = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a, 0,    0,    0,
                              13,   'I', 'H', 'D', 'R',  0,    0,    0,    8,    0,    0,
                              0,    4,   8,   0,   0,    0,    0,    0x5c, 0x6d, 0x1a, 0x36};
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto calib = sparseloop::fuzz::WriteInput(data, size, "kitti/calib.txt");
  const auto dir = calib.parent_path();
  static bool prepared = false;
  if (!prepared) {
    std::filesystem::create_directories(dir / "image_0");
    std::ofstream(dir / "image_0" / "000000.png", std::ios::binary)
        .write(reinterpret_cast<const char*>(kPng), sizeof(kPng));
    std::ofstream(dir / "times.txt") << "0.000000e+00\n";
    prepared = true;
  }
  try {
    sparseloop::OpenDataset("kitti:" + dir.string());
  } catch (const sparseloop::Error&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
