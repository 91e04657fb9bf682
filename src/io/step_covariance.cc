#include "sparseloop/io/step_covariance.h"

#include <cmath>

#include <fmt/format.h>

#include "io/text_parsing.h"
#include "sparseloop/core/covariance.h"
#include "sparseloop/core/error.h"

namespace sparseloop {

std::vector<StepCovariance> ReadStepCovariances(const std::filesystem::path& path) {
  const io_internal::TextFile file(path);
  const auto& name = file.name();
  std::vector<StepCovariance> out;
  for (const auto& line : file.DataLines()) {
    const auto t = io_internal::SplitWhitespace(line.text);
    if (t.size() != 22 && t.size() != 37) {
      throw FileError(name, line.number,
                      "22 columns (key + upper triangle of the 6x6 covariance) or 37 (key + "
                      "the full 6x6 covariance, row-major)",
                      fmt::format("{} columns", t.size()));
    }
    StepCovariance s;
    s.key = io_internal::ParseDouble(t[0], name, line.number, "the key (timestamp or frame)");
    if (!out.empty() && !(s.key > out.back().key)) {
      throw FileError(name, line.number,
                      fmt::format("a key above the previous line's {}", out.back().key),
                      fmt::format("{}", s.key));
    }
    Eigen::Matrix<double, 6, 6>& c = s.covariance;
    size_t k = 1;
    for (int r = 0; r < 6; ++r) {
      for (int col = t.size() == 22 ? r : 0; col < 6; ++col) {
        c(r, col) = io_internal::ParseDouble(t[k++], name, line.number,
                                             fmt::format("covariance entry ({}, {})", r, col));
        if (t.size() == 22) c(col, r) = c(r, col);
      }
    }
    const double scale = c.cwiseAbs().maxCoeff();
    if ((c - c.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
      throw FileError(name, line.number, "a symmetric covariance",
                      "entries (r, c) and (c, r) differ");
    }
    if (const auto problem = CheckCovariance(c))
      throw FileError(name, line.number, problem->expected, problem->got);
    out.push_back(s);
  }
  return out;
}

}  // namespace sparseloop
