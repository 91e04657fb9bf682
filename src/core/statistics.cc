#include "sparseloop/core/statistics.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace sparseloop {

double PercentileOfSorted(const std::vector<double>& sorted, double q) {
  if (!(q >= 0.0 && q <= 1.0)) {
    throw std::invalid_argument(fmt::format("percentile q must be in [0, 1], got {}", q));
  }
  if (sorted.empty()) return 0.0;
  const double rank = q * static_cast<double>(sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(rank));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  const double f = rank - static_cast<double>(lo);
  return f == 0.0 ? sorted[lo] : sorted[lo] + f * (sorted[hi] - sorted[lo]);
}

double Percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return PercentileOfSorted(values, q);
}

}  // namespace sparseloop
