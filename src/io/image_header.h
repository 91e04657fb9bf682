#pragma once
// Internal to io: the JPEG checks OpenDataset runs on every frame's image (no decoding). The image
// size readers themselves (ReadPngSize, ReadImageSize) are public, in sparseloop/io/dataset.h;
// both are defined in image_header.cc.
#include <filesystem>

namespace sparseloop::io_internal {

// True when the file starts with the JPEG SOI marker FF D8.
bool IsJpeg(const std::filesystem::path& path);
// A JPEG's data ends with the EOI marker FF D9 (trailing NUL padding allowed); a truncated file
// does not.
bool JpegEndsWithEoi(const std::filesystem::path& path);

}  // namespace sparseloop::io_internal
