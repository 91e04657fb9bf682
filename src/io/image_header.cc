// Image sizes from file headers, no decoding: PNG (IHDR chunk), JPEG (first SOF marker),
// PGM/PPM/PBM and BMP (ReadPngSize, ReadImageSize of sparseloop/io/dataset.h), and the JPEG
// end-of-image check of OpenDataset (image_header.h).
#include "io/image_header.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "sparseloop/core/error.h"
#include "sparseloop/io/dataset.h"

namespace sparseloop {

namespace fs = std::filesystem;

ImageSize ReadPngSize(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path.string(), 0, "an existing PNG image", "cannot open");
  std::array<unsigned char, 24> h{};
  in.read(reinterpret_cast<char*>(h.data()), h.size());
  static constexpr std::array<unsigned char, 8> kSignature = {0x89, 'P',  'N',  'G',
                                                              0x0D, 0x0A, 0x1A, 0x0A};
  if (in.gcount() != static_cast<std::streamsize>(h.size()) ||
      !std::equal(kSignature.begin(), kSignature.end(), h.begin()) || h[12] != 'I' ||
      h[13] != 'H' || h[14] != 'D' || h[15] != 'R') {
    throw FileError(path.string(), 0, "a PNG file (signature and IHDR chunk)", "other data");
  }
  auto be32 = [&h](size_t o) {
    return (static_cast<uint32_t>(h[o]) << 24) | (static_cast<uint32_t>(h[o + 1]) << 16) |
           (static_cast<uint32_t>(h[o + 2]) << 8) | static_cast<uint32_t>(h[o + 3]);
  };
  const uint32_t w = be32(16);
  const uint32_t hh = be32(20);
  if (w == 0 || hh == 0 || w > (1u << 30) || hh > (1u << 30)) {
    throw FileError(path.string(), 0, "a positive PNG image size", fmt::format("{}x{}", w, hh));
  }
  return {static_cast<int>(w), static_cast<int>(hh)};
}

namespace {

// JPEG: markers from SOI until the first start-of-frame (SOF0..SOF15 but DHT C4, JPG C8, DAC
// CC), whose segment holds precision, height, width.
std::optional<ImageSize> ReadJpegSize(std::istream& in) {
  for (;;) {
    if (in.get() != 0xFF) return std::nullopt;  // not at a marker: corrupt
    int marker = in.get();
    while (marker == 0xFF) marker = in.get();  // fill bytes
    if (marker == EOF) return std::nullopt;
    if (marker == 0x01 || marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7)) continue;
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // no frame header before the scan
    const int hi = in.get(), lo = in.get();
    if (lo == EOF || ((hi << 8) | lo) < 2) return std::nullopt;
    const int length = (hi << 8) | lo;
    const bool sof =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (!sof) {
      in.seekg(length - 2, std::ios::cur);
      continue;
    }
    std::array<unsigned char, 5> f{};
    if (!in.read(reinterpret_cast<char*>(f.data()), f.size())) return std::nullopt;
    const int height = (f[1] << 8) | f[2], width = (f[3] << 8) | f[4];
    if (width == 0 || height == 0) return std::nullopt;  // height 0: defined later (DNL)
    return ImageSize{width, height};
  }
}

// PGM/PPM/PBM ("P1".."P6"): width and height are the first two numbers after the magic, with
// '#' comments running to the end of their line.
std::optional<ImageSize> ReadPnmSize(std::istream& in) {
  int values[2] = {0, 0};
  for (int& v : values) {
    int c = in.get();
    while (c == '#' || std::isspace(c)) {
      if (c == '#') {
        while (c != '\n' && c != EOF) c = in.get();
      }
      c = in.get();
    }
    if (!std::isdigit(c)) return std::nullopt;
    for (; std::isdigit(c) && v < (1 << 24); c = in.get()) v = 10 * v + (c - '0');
  }
  if (values[0] <= 0 || values[1] <= 0) return std::nullopt;
  return ImageSize{values[0], values[1]};
}

// BMP: the DIB header after the 14-byte file header; BITMAPCOREHEADER (12 bytes, 16-bit sizes)
// or a larger one (32-bit signed sizes; a negative height is a top-down bitmap).
std::optional<ImageSize> ReadBmpSize(std::istream& in) {
  std::array<unsigned char, 24> h{};  // bytes 2..25 of the file
  if (!in.read(reinterpret_cast<char*>(h.data()), h.size())) return std::nullopt;
  auto le = [&h](size_t file_offset, int bytes) {
    uint32_t v = 0;
    for (int b = bytes - 1; b >= 0; --b) v = (v << 8) | h[file_offset - 2 + b];
    return v;
  };
  const uint32_t dib = le(14, 4);
  int64_t width = 0, height = 0;
  if (dib == 12) {
    width = le(18, 2), height = le(20, 2);
  } else if (dib >= 40) {
    width = static_cast<int32_t>(le(18, 4)), height = static_cast<int32_t>(le(22, 4));
  }
  height = std::abs(height);
  if (width <= 0 || height <= 0 || width > (1 << 30) || height > (1 << 30)) return std::nullopt;
  return ImageSize{static_cast<int>(width), static_cast<int>(height)};
}

}  // namespace

namespace io_internal {

// A JPEG's data ends with the EOI marker FF D9 (trailing NUL padding allowed); a truncated file
// does not.
bool JpegEndsWithEoi(const fs::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 4096);
  std::string bytes(static_cast<size_t>(std::max<std::streamoff>(tail, 0)), '\0');
  in.seekg(size - tail);
  if (!in || !in.read(bytes.data(), tail)) return false;
  while (!bytes.empty() && bytes.back() == '\0') bytes.pop_back();
  return bytes.size() >= 2 && static_cast<unsigned char>(bytes[bytes.size() - 2]) == 0xFF &&
         static_cast<unsigned char>(bytes.back()) == 0xD9;
}

bool IsJpeg(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return in.get() == 0xFF && in.get() == 0xD8;
}

}  // namespace io_internal

std::optional<ImageSize> ReadImageSize(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const int m0 = in.get(), m1 = in.get();
  if (m0 == 0x89 && m1 == 'P') {
    in.seekg(0);
    std::array<char, 24> h{};
    if (!in.read(h.data(), h.size()) || std::string_view(h.data() + 1, 3) != "PNG" ||
        std::string_view(h.data() + 12, 4) != "IHDR") {
      return std::nullopt;
    }
    return ReadPngSize(path);
  }
  if (m0 == 0xFF && m1 == 0xD8) return ReadJpegSize(in);
  if (m0 == 'P' && m1 >= '1' && m1 <= '6') return ReadPnmSize(in);
  if (m0 == 'B' && m1 == 'M') return ReadBmpSize(in);
  return std::nullopt;
}

}  // namespace sparseloop
