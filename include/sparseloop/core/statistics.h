#pragma once
// The one definition of a percentile used for every reported statistic (timings, error
// statistics, summaries): linear interpolation between the closest ranks, NumPy's default
// (`numpy.percentile(..., method="linear")`), so the median of an even count is the mean of the
// two middle values, as evo and numpy.median report it.
#include <vector>

namespace sparseloop {

// q in [0, 1]: the value at rank q * (n - 1) of the sorted values, interpolated. 0 for no values.
// Throws std::invalid_argument for q outside [0, 1] or NaN.
double Percentile(std::vector<double> values, double q);

// The same on values already sorted ascending (no copy).
double PercentileOfSorted(const std::vector<double>& sorted, double q);

// The p-quantile of the chi-square distribution with `dof` degrees of freedom (Wilson-Hilferty on
// the normal quantile; for dof >= 3 within 1.5 % of the tables at p >= 0.5 and 3 % in the lower
// tail). Throws
// std::invalid_argument for p outside (0, 1) or dof < 1.
double ChiSquareQuantile(double p, int dof);

}  // namespace sparseloop
