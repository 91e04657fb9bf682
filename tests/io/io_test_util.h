#pragma once
// Small helpers for the io tests: write a text file, write a minimal PNG header.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace sparseloop::test {

inline std::filesystem::path WriteText(const std::filesystem::path& path,
                                       const std::string& content) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << content;
  return path;
}

inline std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A PNG signature + IHDR chunk (no image data): enough for ReadPngSize.
inline void WritePngHeader(const std::filesystem::path& path, uint32_t width, uint32_t height) {
  std::filesystem::create_directories(path.parent_path());
  std::string bytes = "\x89PNG\r\n\x1a\n";
  bytes += std::string("\0\0\0\x0d", 4) + "IHDR";
  for (uint32_t v : {width, height}) {
    for (int s = 24; s >= 0; s -= 8) bytes.push_back(static_cast<char>((v >> s) & 0xff));
  }
  bytes += std::string("\x08\x00\x00\x00\x00", 5) + std::string(4, '\0');
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

}  // namespace sparseloop::test
