#pragma once
// Fuzz helpers: the parsers under test read files, so each input is written to a per-process
// temporary file first.
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace sparseloop::fuzz {

inline std::filesystem::path WriteInput(const uint8_t* data, size_t size, const std::string& name) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("sparseloop_fuzz_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const auto path = dir / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace sparseloop::fuzz
