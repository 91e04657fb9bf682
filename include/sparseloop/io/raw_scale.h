#pragma once
// raw_scale.txt of `sparseloop render` (docs/FORMATS.md, "Synthetic sequences"): one number per
// frame, the raw trajectory's scale there (raw units per GT metre). '#' comments and blank lines
// are skipped; any line ending and a BOM read alike. Throws FileError naming the file and the line
// for a line that is not one positive finite number.
#include <filesystem>
#include <vector>

namespace sparseloop {

std::vector<double> ReadRawScale(const std::filesystem::path& path);

}  // namespace sparseloop
