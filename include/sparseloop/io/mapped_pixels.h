#pragma once
// The pixels a vSLAM mapped in one keyframe, as `sparseloop render` writes them and `run` reads
// them (DIR/mapped/NNNNNN.txt, docs/FORMATS.md): one "u v depth" line per pixel, depth in the raw
// trajectory's units, <= 0 unknown. '#' comments and blank lines are skipped; a BOM, "\r\n" and
// lone "\r" line ends read as "\n" files do. Malformed input throws FileError naming the file and
// the 1-based line: a column count other than 3, a number that does not parse or is not finite
// as a float (|x| > 3.4e38: 1e39 would be inf).
#include <filesystem>
#include <vector>

namespace sparseloop {

struct MappedPixelRow {
  float u = 0.0f;
  float v = 0.0f;
  float depth = 0.0f;
};

std::vector<MappedPixelRow> ReadMappedPixelRows(const std::filesystem::path& path);

}  // namespace sparseloop
